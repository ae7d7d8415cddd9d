"""What a glossy object's model is made of, fitted part by part.

    colour(x, w) = emitted(x)                               every object
                 + E(x, w)                                   the emitters' own highlights, in closed
                                                             form (``radiosity.physics.emitters``)
                 + s(x) S(n . w) P(u(x, w))                  a reflection probe (``fitting.probe``)
                 + sum_k c_k(x) lobe_k(x, w)                 virtual lights for the rest (``mixed``)

The emitter term is not fitted: the solution holds it (``Solution.highlights``), so what
is fitted is the rest, R = L - E, and every display adds E back. The probe draws the
broad reflections of the surroundings, the lights what remains (a lamp seen in a glossy
neighbour, an object the probe's box does not know).

Models, cheapest first (``MODELS``): "diffuse" (emitted alone), "emitters", "probe"
(emitters + probe), "probe+lights", and "lights" (virtual lights on the whole radiance,
no emitter term: the paper's model and its extensions). "auto" fits
them all (the probe at several sizes; lights only where the rest still shows a
highlight) and keeps, in order of stored floats, the first whose error in a space near
what a viewer sees (``data.perceptual_error``, against the solution's whole radiance)
reaches the target or comes within ``WITHIN`` of the best one's: more floats that buy
less are not kept. With ``--loss auto`` it fits its first probe with both losses and
takes the linear one where the relative one fails (``_choose_loss``).

The floor: "auto" never keeps a model whose perceptual error exceeds the diffuse
walkthrough's. Its "diffuse" candidate is exactly what that walkthrough draws, each
vertex's radiance averaged over the (equal-area) direction grid, measured the same way
as every other candidate; a model worse than it is tried, reported and not kept (a
highlight's lights included), and when every other model is worse the object keeps
"diffuse" and says so (``Components.why``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from . import mixed, probe
from .blocks import BLOCK_SAMPLES, SEARCH_SAMPLES, object_mean, search_slice, vertex_blocks
from .data import ErrorSums, FitData, fit_data, object_areas, perceptual_error, relative_error
from .lights import lights_on_every_vertex, reconstruct
from .loss import loss_weights as make_loss_weights
from .options import GLOSSY_MODELS
from .results import Lights

__all__ = ["MODELS", "Components", "fit_components"]

MODELS = GLOSSY_MODELS
PROBE_SIZES = (8, 16, 32)
WITHIN = 0.03  # "auto" keeps a cheaper model whose error is within this fraction of the best's
FIRST_LIGHT_PAYS = 0.02  # "auto" fits more lights beside a probe only if the first lowers the perceptual error this much
HIGHLIGHT = 1.0  # a residual peak above this times the object's mean radiance is a highlight: lights fit it
BOX_MARGIN = 1e-3  # the probe's proxy box: the scene's bounds grown by this fraction of their diagonal
WARM_ROUNDS = 3  # alternations of a probe fit that starts from another's coefficients
PROBE_SAMPLES = 2_000_000  # the texels are fitted to at most about this many samples (every k-th vertex's)
BLOCK_FLOATS = 1 << 24  # the per-vertex solves' design matrices, a block of vertices at a time (128 MB)
AUTO_LOSSES = ("relative", "linear")  # the losses "auto" chooses between (``_choose_loss``)
QUICK_SAMPLES = 1 << 14  # lights alone are fitted quickly on every k-th vertex, about this many samples, first (``_lights_alone``)
SCREEN = 2 * math.log(1.25)  # lights alone are refined in full where a quick fit's error is within 1.25 x what pays
LOSS_MARGIN = 0.1  # "auto" takes the linear loss where its first probe's perceptual error is this much below the relative's


@dataclass(frozen=True, eq=False)
class Components:
    """One glossy object's fitted model.

    model: one of MODELS; emitters: whether the emitter term is part of it;
    emitted (V, 3); lights: a ``results.Lights`` (pos (K, 4), rgb (K, 3), shininess (K,));
    specular (V, K, 3) per light or (V, 3) shared; probe: a ``fitting.probe.Probe`` or
    None, probe_weight (V, 3) its per-vertex s; error: relative RMS against the whole
    radiance; floats: the numbers stored (per vertex x V + per object); perceptual: the
    error ``data.perceptual_error``; tried: what "auto" compared, one dict per model
    (model, probe_size, lights, floats, relative_rms, perceptual; "kept": False for a
    step on the way, "above_floor": True for a model worse than the diffuse
    walkthrough); baseline: the relative RMS of each vertex's directional mean (the
    diffuse walkthrough); why: why "auto" kept this model (one line; "" otherwise)
    """

    model: str
    emitters: bool
    emitted: np.ndarray
    lights: Lights
    specular: np.ndarray
    probe: probe.Probe | None
    probe_weight: np.ndarray | None
    error: float
    floats: int
    perceptual: float = 0.0
    tried: list = field(default_factory=list)
    baseline: float = 0.0  # the relative RMS of each vertex's directional mean (a diffuse walkthrough)
    why: str = ""
    loss: str | None = None  # the loss it was fitted with (``fitting.loss``); None: no fit (the directional mean)
    chosen_by: str = ""  # the model "lights" asked for: how its count was chosen (--lights K, or "auto"'s reason)
    worst: dict = field(default_factory=dict)  # the model "lights": its worst vertex and the walkthrough's (relative RMS)
    iterations: int = 0  # the model "lights": the refinement's iterations

    @property
    def n_lights(self):
        return len(self.lights[0])


def _floats(n_vertices, parts, probe_size, n_lights, emitters, shared=False):
    """The numbers a model stores: per vertex its emitted colour, its emitters'
    visibility, its probe weight and its lights' coefficients (three a light, or three
    in all where they are ``shared``), and per object its probe's texels and lights."""
    per_vertex = 3 + (parts if emitters else 0) + (3 if probe_size else 0) + 3 * (min(n_lights, 1) if shared else n_lights)
    return per_vertex * n_vertices + 3 * probe_size * probe_size + 8 * n_lights


def proxy_box(solution):
    """The probe's proxy: the scene's bounding box (every object of ``solution``), grown a little."""
    return proxy_box_of(o.positions for o in solution.objects)


def proxy_box_of(positions):
    """``proxy_box`` of the objects' vertex positions (an iterable of (V, 3))."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for p in positions:
        p = np.asarray(p, np.float64)
        if len(p):
            lo, hi = np.minimum(lo, p.min(axis=0)), np.maximum(hi, p.max(axis=0))
    pad = BOX_MARGIN * float(np.linalg.norm(hi - lo))
    return np.stack([lo - pad, hi + pad])


def _lobe_columns(data, lights):
    """(V, D, K) each light's lobe at the data's samples (its colour one)."""
    pos, _, shininess = lights
    n_k = len(pos)
    out = np.empty(data.radiance.shape[:2] + (n_k,))
    samples = mixed.Samples(np.ascontiguousarray(data.positions), np.ascontiguousarray(data.radiance),
                            np.ascontiguousarray(data.weights), np.ones((1, 1, 1)))
    one = np.ones((data.n_vertices, 1, 3))
    tmp = np.empty(data.radiance.shape)
    for k in range(n_k):
        light = Lights.of(pos[k:k + 1], np.ones((1, 3)), shininess[k:k + 1])
        mixed.mixed_light_sum(data.normals, data.views, light, samples, one, tmp)
        out[:, :, k] = tmp[:, :, 0]
    return out


class _LightColumns(NamedTuple):
    """The lights' columns of ``_joint``: per light, ``values`` (V, D, K) each light's
    lobe (its colour one) and ``caps`` (V, 3, K) its coefficient's; ``shared`` (one
    coefficient a vertex, the paper's model): ``values`` (V, D, 3) the lights' sum,
    sum_k rgb_k lobe_k, and ``caps`` (V, 3) its coefficient's."""

    values: np.ndarray
    caps: np.ndarray
    shared: bool

    def term(self, c):
        """(V, D, 3) the lights' part of the model with coefficients ``c`` (``_joint``'s)."""
        if self.shared:
            return c[:, None, :] * self.values
        return np.einsum("vdk,vkc->vdc", self.values, c)


def _light_columns(data, lights, shared):
    """``_LightColumns`` of ``lights`` (pos, rgb, shininess) at the samples of ``data``;
    ``shared``: one coefficient a vertex for them all, which multiplies each light's
    colour (per-light coefficients carry the colour: their lights' are ones)."""
    lobes = _lobe_columns(data, lights)
    caps = _light_caps(data, lights)
    if not shared:
        return _LightColumns(lobes, caps, False)
    rgb = np.asarray(lights[1], np.float64)
    # the shared coefficient's cap is the tightest the lights set: CAP_FACTOR x the brightest
    # radiance over the brightest lobe shown, max_k peak_k rgb_k (as ``mixed.coefficients``)
    with np.errstate(divide="ignore", invalid="ignore"):
        cap = np.min(np.where(rgb.T[None] > 0, caps / rgb.T[None], np.inf), axis=2)
    return _LightColumns(np.einsum("vdk,kc->vdc", lobes, rgb), np.minimum(cap, 1e200), True)


def _joint(data, target, loss_weights, probe_values, lights=None):
    """Per-vertex coefficients [emitted, probe weight?, light coefficients...] >= 0 of
    ``target`` (V, D, 3) with the columns given (probe_values (V, D, 3) or None, lights a
    ``_LightColumns`` or None); returns (emitted (V, 3), probe weight (V, 3) or None, c:
    (V, K, 3) per light, (V, 3) shared, (V, 0, 3) without lights). Vertices are solved a
    block at a time (the design is (V, D, columns, 3))."""
    v, d, _ = target.shape
    n_k = 0 if lights is None else (1 if lights.shared else lights.values.shape[2])
    n = 1 + (probe_values is not None) + n_k
    x = np.empty((v, 3, n))
    block = max(1, BLOCK_FLOATS // max(d * n * 3, 1))
    for start in range(0, v, block):
        sl = slice(start, start + block)
        b = len(range(*sl.indices(v)))
        columns = [np.ones((b, d, 1, 3))]
        if probe_values is not None:
            columns.append(probe_values[sl, :, None, :])
        cap = np.full((b, 3, n), 1e200)
        if lights is not None and lights.shared:
            columns.append(lights.values[sl, :, None, :])
            cap[:, :, n - 1] = lights.caps[sl]
        elif n_k:
            columns.append(np.broadcast_to(lights.values[sl, :, :, None], (b, d, n_k, 3)))
            cap[:, :, n - n_k:] = lights.caps[sl]
        columns = np.concatenate(columns, axis=2)
        lw = None if loss_weights is None or loss_weights.shape[0] == 1 else loss_weights[sl]
        x[sl], _ = probe.vertex_coefficients(columns, target[sl], data.weights[sl], lw, cap)
    emitted = x[:, :, 0]
    weight = x[:, :, 1] if probe_values is not None else None
    if lights is not None and lights.shared:
        return emitted, weight, np.ascontiguousarray(x[:, :, n - 1])
    c = np.transpose(x[:, :, n - n_k:], (0, 2, 1)) if n_k else np.zeros((v, 0, 3))
    return emitted, weight, np.ascontiguousarray(c)


def _light_caps(data, lights):
    """(V, 3, K) the per-light coefficients' caps, as ``mixed.coefficients`` sets them."""
    pos, _, shininess = lights
    unit = mixed.light_vectors(pos, data.positions)
    theta = np.arccos(np.clip(np.einsum("vi,vki->vk", data.normals, unit), -1.0, 1.0))
    peak = np.cos(np.maximum(theta - np.pi / 2, 0.0) / 2) ** shininess[None, :]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # a subnormal peak: the cap is 1e200
        cap = np.where(peak[:, None, :] > 0, mixed.CAP_FACTOR * data.radiance.max(axis=1)[:, :, None] / peak[:, None, :], 0.0)
    return np.minimum(cap, 1e200)


def fit_probe_part(data, target, loss_weights, size, centre, box, albedo, *, fixed=None, rounds=probe.ALTERNATIONS,
                   start=None):
    """(Probe, emitted (V, 3), probe weight (V, 3), values) for ``target`` (V, D, 3) minus
    ``fixed`` (V, D, 3) (another part of the model, kept), by alternating least squares;
    ``albedo``: the table of S (``probe.albedo_table``); ``start``: (emitted, weight) to
    begin from (default: each vertex's least radiance and 1). values (V, D, 3): the
    probe's S P(u) at every sample, as ``probe.probe_values`` gives them (to rounding:
    the texels are the stored float32 ones), so that no caller evaluates them again."""
    rest = target if fixed is None else target - fixed
    v, d = data.n_vertices, data.n_directions
    # the texels from every step-th vertex (at most PROBE_SAMPLES samples: a large
    # object's probe sees plenty of its surroundings), the vertices' coefficients from all
    step = max(1, math.ceil(v * d / PROBE_SAMPLES))
    sub = np.arange(0, v, step)

    def look_ups(vertices):
        u = probe.box_directions(data.positions[vertices, None, :], data.views[vertices],
                                 data.normals[vertices, None, :], centre, box)
        idx, wts, cells = probe.texels(u.reshape(-1, 3), size, cells=True)
        factor = probe.albedo_factor(albedo, data.normals[vertices, None, :], data.views[vertices])
        return idx, wts * factor.reshape(-1, 1), cells  # S folds into the look-up's weights

    idx, wts, cells = look_ups(sub)
    # every vertex's look-ups, kept where they fit (else made again a block at a time each round)
    block = max(1, BLOCK_FLOATS // (d * 3))
    kept = (idx, wts) if step == 1 else (look_ups(np.arange(v))[:2] if v * d <= 4 * PROBE_SAMPLES else None)
    weight = data.weights[sub].reshape(-1)
    lw = None if loss_weights is None or loss_weights.shape[0] == 1 else loss_weights[sub].reshape(-1, 3)
    sample_weight = weight[:, None] * (1.0 if lw is None else lw)
    if start is None:
        emitted = np.maximum(rest.min(axis=1), 0.0)
        scale = np.ones_like(emitted)
    else:
        emitted, scale = (np.asarray(a, np.float64) for a in start)
    texels = np.zeros((size, size, 3))
    values = np.empty(rest.shape)
    for _ in range(rounds):
        s_rep = np.repeat(scale[sub], d, axis=0)
        e_rep = np.repeat(emitted[sub], d, axis=0)
        texels = probe.solve_texels(idx, wts, cells, sample_weight, rest[sub].reshape(-1, 3) - e_rep, s_rep, size)
        # the scale between P and s is free: keep s near 1 where the object is
        mean = np.sum(data.weights.sum(axis=1)[:, None] * scale, axis=0) / max(data.weights.sum(), 1e-300)
        texels *= np.where(mean > 0, mean, 1.0)
        texels = texels.astype(np.float32).astype(np.float64)  # what the model stores
        flat = texels.reshape(-1, 3)
        if kept is not None:
            values[:] = np.einsum("sk,skc->sc", kept[1], flat[kept[0]]).reshape(v, d, 3)
        else:
            for first in range(0, v, block):
                part = np.arange(first, min(v, first + block))
                i, w, _ = look_ups(part)
                values[part] = np.einsum("sk,skc->sc", w, flat[i]).reshape(len(part), d, 3)
        emitted, scale, _ = _joint(data, rest, loss_weights, values)
    found = probe.Probe(texels.astype(np.float32), np.asarray(centre, np.float64), np.asarray(box, np.float64),
                        np.asarray(albedo, np.float64))
    return found, emitted, scale, values


def _model(highlights, emitted, probe_term, light_term):
    out = emitted[:, None, :] + highlights
    if probe_term is not None:
        out = out + probe_term
    if light_term is not None:
        out = out + light_term
    return out


def fit_components(obj, highlights, parts, options, scene, box, exponent, fit_lights, *, probe_sizes=PROBE_SIZES,
                   search_samples=SEARCH_SAMPLES, block_samples=BLOCK_SAMPLES):
    """The ``Components`` of one glossy ``ObjectSolution`` ``obj``.

    highlights: the emitter term on its grid (zeros without emitters), (V, D, 3), or a
    function of a slice of vertices giving theirs; parts: the emitter parts' count;
    options: ``FitOptions`` (model, probe_size, loss, target, lights...); scene: the
    ``mixed.SceneGeometry``; box: the probe's proxy (2, 3); exponent: where the lights'
    exponent starts; fit_lights: a ``fitting.lights.LightFitter`` (the lights of every
    model with lights, the model "lights" asked for included: ``_lights_asked``);
    probe_sizes: what "auto" tries. The model is searched for on every k-th vertex, at
    most ``search_samples`` samples, and its per-vertex coefficients then solved on
    every vertex, ``block_samples`` samples at a time (``fitting.blocks``); an object
    of at most ``search_samples`` samples is fitted whole."""
    of = highlights if callable(highlights) else (lambda vertices: highlights[vertices])
    n_vertices, n_directions = obj.num_vertices, len(obj.directions)
    area = object_areas(obj)
    sub = search_slice(n_vertices, n_directions, search_samples)
    full = fit_data(obj, sub, area)
    if options.glossy_model == "lights":
        return _lights_asked(obj, full, options, fit_lights, exponent, (sub, area))
    positions = np.asarray(obj.positions, np.float64)
    centre = 0.5 * (positions.min(axis=0) + positions.max(axis=0))
    del positions
    found = _search(full, np.asarray(of(sub), np.float64), obj.material_record, n_vertices, parts, options,
                    place=(centre, box), exponent=exponent, fit_lights=fit_lights, probe_sizes=probe_sizes)
    if sub.step == 1:
        return found
    return _every_vertex(found, obj, of, area, options, (sub, block_samples))


def _lights_asked(obj, full, options, lights, exponent, blocking):
    """The ``Components`` of the model "lights" asked for (``--model lights``, the
    paper's method): virtual lights alone on the whole radiance, found on ``full`` (every
    k-th vertex), then their per-vertex coefficients solved on every vertex by the
    lights' own projection (``lights.lights_on_every_vertex``), as the paper solves them.
    lights: a ``fitting.lights.LightFitter``; blocking = (the search's slice, the areas)."""
    sub, area = blocking
    loss = options.loss_for("lights")
    problem, found, chosen_by = lights.asked(full, make_loss_weights(full, loss), exponent)
    n_vertices = obj.num_vertices
    if (sub.step or 1) > 1:
        del full, problem
        found, error, diffuse, seen = lights_on_every_vertex(obj, found, options, lights.scene, area)
        chosen_by += f"; found on every {sub.step}-th vertex ({len(range(*sub.indices(n_vertices))):,} of {n_vertices:,})"
    else:
        approximation = reconstruct(problem, found)
        error, seen = relative_error(full, approximation), perceptual_error(full, approximation)
        diffuse = relative_error(full, np.broadcast_to(found.emitted[:, None, :], full.radiance.shape))
    return Components(
        model="lights", emitters=False, emitted=found.emitted, lights=found.lights(),
        specular=found.specular, probe=None, probe_weight=None, error=error["relative_rms"],
        floats=_floats(n_vertices, 0, 0, found.n_lights, False, not found.per_light), perceptual=seen,
        baseline=diffuse["relative_rms"], loss=loss, chosen_by=chosen_by, iterations=found.iterations,
        worst={"worst_vertex": error["worst_vertex"], "worst_vertex_index": error["worst_vertex_index"],
               "diffuse_only_worst_vertex": diffuse["worst_vertex"]},
    )


def _search(full, highlights, material, n_vertices, parts, options, *, place, exponent, fit_lights, probe_sizes):
    """``fit_components`` on ``full`` (the ``FitData`` of the object or of a subset of
    its vertices, ``highlights`` theirs): the model "auto" chooses, or the one asked
    for; n_vertices: the object's (what a model stores counts them all); place: the
    probe's centre (the whole object's) and proxy box."""
    v = full.n_vertices
    centre, box = place
    rest = full.radiance - highlights
    data = FitData(radiance=rest, views=full.views, normals=full.normals, weights=full.weights, positions=full.positions)
    wanted = options.model
    automatic = wanted == "auto"
    # the loss weights, of what a viewer sees (the whole radiance), of each loss fitted
    # ("auto" may try both: ``_choose_loss``)
    weights = {options.loss_for("probe"): make_loss_weights(full, options.loss_for("probe"))}
    albedo = probe.albedo_table(material.exponent)
    tried, fits = [], []

    def record(model, size, emitters, emitted, *, light_fit=None, probe_fit=None, weight=None, probe_term=None,
               light_term=None, keep=True, loss=None):
        # keep=False: a step on the way (tried, shown in the report), not a model "auto" may choose;
        # loss: what it was fitted with (None: the diffuse walkthrough's mean, no fit)
        n_lights = 0 if light_fit is None else len(light_fit[0])
        floats = _floats(n_vertices, parts, size, n_lights, emitters, light_fit is not None and light_fit[3].ndim == 2)
        approximation = _model(highlights if emitters else 0.0, emitted, probe_term, light_term)
        error = relative_error(full, approximation)["relative_rms"]
        seen = perceptual_error(full, approximation)
        c = Components(
            model=model, emitters=emitters, emitted=emitted,
            lights=Lights(*light_fit[:3]) if light_fit is not None else Lights.none(),
            specular=(np.zeros((v, 0, 3)) if light_fit is None else light_fit[3]), probe=probe_fit,
            probe_weight=weight, error=error, floats=floats, perceptual=seen, loss=loss,
        )
        row = {"model": model, "probe_size": size, "lights": n_lights, "floats": floats,
               "relative_rms": round(error, 5), "perceptual": round(seen, 5), **({} if keep else {"kept": False}),
               **({} if loss is None else {"loss": loss})}
        if _above(c, floor):  # "auto" will not keep it (``_choose``)
            row["above_floor"] = True
        tried.append(row)
        if keep:
            fits.append(c)
        return c

    floor = None
    if automatic or wanted == "diffuse":
        # what the diffuse walkthrough draws: the floor no kept model may be worse than
        floor = record("diffuse", 0, False, directional_mean(full.radiance))

    def weigh(kept):
        # lights alone, weighed against what "auto" keeps of the others; not fitted where
        # that reaches the target with fewer floats than they would store (the fewest:
        # --lights auto may stop at one), since "auto" keeps the cheapest reaching it
        fewest = 1 if options.lights == "auto" else options.lights
        least = _floats(n_vertices, 0, 0, fewest, False, options.coefficients == "shared")
        if fewest == 0 or (kept.perceptual <= options.model_target and least >= kept.floats):
            return kept
        samples = 3.0 * full.n_directions * n_vertices
        alone = _lights_alone(record, full, weights, options.loss_for("lights"), exponent, fit_lights,
                              _criterion(kept, samples), (n_vertices, samples))
        return _or_alone(kept, alone, floor, samples, options.model_target)
    loss = options.loss_for("probe")
    if automatic or wanted == "emitters":
        e, _, _ = _joint(data, rest, weights[loss], None)
        record("emitters", 0, True, e, loss=loss)
    if automatic or wanted in ("probe", "probe+lights"):
        if options.probe_size != "auto":
            sizes = [options.probe_size]
        else:
            sizes = list(probe_sizes) if automatic else [max(probe_sizes)]
        first = None
        if automatic and options.loss == "auto":
            loss, first = _choose_loss(record, (data, rest, full, highlights), weights, (sizes[0], centre, box, albedo))
            if loss != "relative" and parts:  # without an emitter term its colour would be the directional mean
                e, _, _ = _joint(data, rest, weights[loss], None)
                record("emitters", 0, True, e, loss=loss)
        best, start = None, None
        for size in sizes:
            if first is not None and size == sizes[0]:
                p, e, s, values = first  # fitted while choosing the loss
                first = None
            else:
                # each size after the first starts from the coefficients of the one before
                p, e, s, values = fit_probe_part(data, rest, weights[loss], size, centre, box, albedo, start=start,
                                                 rounds=probe.ALTERNATIONS if start is None else WARM_ROUNDS)
            start = (e, s)
            term = s[:, None, :] * values
            c = record("probe", size, True, e, probe_fit=p, weight=s, probe_term=term, loss=loss)
            if best is None or c.perceptual < best[0].perceptual * (1 - WITHIN):
                best = (c, term, values)
            del values
        chosen, probe_term, chosen_values = best
        del best
        left = rest - probe_term - chosen.emitted[:, None, :]
        highlight = _shows_highlight(left, full)
        if wanted == "probe+lights" or (automatic and highlight):
            # the lights with the loss of the probe they join
            _probe_and_lights(record, full, data, rest, weights[chosen.loss], (chosen, chosen_values), probe_term,
                              place=(centre, box, albedo), exponent=exponent, fit_lights=fit_lights,
                              required=wanted == "probe+lights")
        if automatic and highlight and fits[-1].n_lights:
            # a highlight neither the emitters nor the probe draw: the object keeps lights,
            # unless every model with lights is worse than the diffuse walkthrough
            with_lights = [f for f in fits if f.n_lights]
            if any(not _above(f, floor) for f in with_lights):
                return weigh(_choose(with_lights, options.model_target, tried, full, floor,
                                     reason="a highlight the probe does not draw: the cheapest model with lights"))
            return weigh(_choose(fits, options.model_target, tried, full, floor, unfloored=with_lights))
    if automatic:
        return weigh(_choose(fits, options.model_target, tried, full, floor))
    return _with_tried([f for f in fits if f.model == wanted][-1], tried, full)


def _every_vertex(c, obj, highlights_of, area, options, blocking):
    """The ``Components`` ``c`` found on a subset of the vertices (``fit_components``),
    its per-vertex coefficients solved on every vertex with its probe's texels and its
    lights held, a block of vertices at a time, and its errors measured on them all.
    blocking = (the subset's slice, the block's samples)."""
    sub, block_samples = blocking
    v, d = obj.num_vertices, len(obj.directions)
    mean = object_mean(obj.radiance, area, block_samples)
    n_k = c.n_lights
    emitted = np.empty((v, 3))
    weight = None if c.probe is None else np.empty((v, 3))
    specular = np.empty((v, 3) if c.specular.ndim == 2 else (v, n_k, 3))
    model, baseline = ErrorSums(mean), ErrorSums(mean)
    for sl in vertex_blocks(v, d, block_samples):
        full = fit_data(obj, sl, area)
        highlights = np.asarray(highlights_of(sl), np.float64) if c.emitters else 0.0
        rest = full.radiance - highlights  # the model "lights" (no emitter term): the whole radiance
        data = FitData(radiance=rest, views=full.views, normals=full.normals, weights=full.weights,
                       positions=full.positions)
        walkthrough = directional_mean(full.radiance)
        values = probe_term = light_term = None
        if c.model == "diffuse":
            e = walkthrough
        else:
            lw = None if c.loss is None else make_loss_weights(full, c.loss, mean)
            if c.probe is not None:
                values = _probe_values(data, c.probe)
            lights = _light_columns(data, c.lights, c.specular.ndim == 2) if n_k else None
            e, s, k = _joint(data, rest, lw, values, lights)
            del lw
            if values is not None:
                weight[sl] = s
                probe_term = s[:, None, :] * values
            if n_k:
                specular[sl] = k
                light_term = lights.term(k)
            del lights
        emitted[sl] = e
        model.add(full, _model(highlights if c.emitters else 0.0, e, probe_term, light_term), sl.start)
        baseline.add(full, np.broadcast_to(walkthrough[:, None, :], full.radiance.shape), sl.start)
    on = f"chosen on every {sub.step}-th vertex ({len(range(*sub.indices(v))):,} of {v:,})"
    return replace(c, emitted=emitted, probe_weight=weight, specular=specular, error=model.relative()["relative_rms"],
                   perceptual=model.perceptual(), baseline=baseline.relative()["relative_rms"],
                   why=f"{c.why}; {on}" if c.why else on)


def _probe_values(data, found):
    """S(n . w) P(u) (V, D, 3) at the samples of ``data`` (its vertices' look-ups in the
    probe ``found``'s stored texels), as ``fit_probe_part``'s values."""
    u = probe.box_directions(data.positions[:, None, :], data.views, data.normals[:, None, :], found.centre, found.box)
    idx, wts = probe.texels(u.reshape(-1, 3), found.size)
    del u
    wts *= probe.albedo_factor(found.albedo, data.normals[:, None, :], data.views).reshape(-1, 1)
    flat = np.asarray(found.texels, np.float64).reshape(-1, 3)
    return np.einsum("sk,skc->sc", wts, flat[idx]).reshape(data.radiance.shape)


def _lights_alone(record, full, weights, loss, exponent, fit_lights, beat, sizes):
    """The model "lights" as "auto" weighs it: virtual lights on the whole radiance (no
    emitter term, no probe), as many as --lights says, with ``loss`` (``weights`` gains
    its weights), their per-vertex coefficients solved as every other model's; None if
    no light was fitted. First a quick fit (``mixed.FIRST_POLISH_ITERATIONS``
    iterations, on every k-th vertex: at most QUICK_SAMPLES samples), a step on the way in the
    report; the whole fit only where the quick one's error comes within SCREEN of the
    criterion ``beat`` (``_criterion`` of what "auto" keeps of the others). sizes =
    (the object's vertices, the samples the criterion counts). Weighed with a quick fit
    on the search's vertices, they more than doubled the living room's fit on one core
    (435 s without them; stopped after 965 s)."""
    n_vertices, samples = sizes
    if loss not in weights:
        weights[loss] = make_loss_weights(full, loss)
    lw = weights[loss]

    def solved(data, data_lw, found):
        # (emitted, coefficients, the lights' term) of the lights ``found`` at the samples of ``data``
        columns = _light_columns(data, (found.pos, found.rgb, found.shininess), not found.per_light)
        e, _, c = _joint(data, data.radiance, data_lw, None, columns)
        return e, c, columns.term(c)

    def candidate(found, keep):
        e, c, term = solved(full, lw, found)
        return record("lights", 0, False, e, light_fit=(found.pos, found.rgb, found.shininess, c), light_term=term,
                      loss=loss, keep=keep)

    idx = np.arange(0, full.n_vertices, max(1, math.ceil(full.n_vertices * full.n_directions / QUICK_SAMPLES)))
    few, few_lw = full.vertices(idx), lw[idx] if lw is not None and lw.shape[0] > 1 else lw
    quick = fit_lights(few, few_lw, exponent, alone=True, count=0)
    if not quick.n_lights:
        return None
    e, _, term = solved(few, few_lw, quick)
    error = perceptual_error(few, e[:, None, :] + term)
    del e, term
    first = candidate(quick, False)
    if _information(error, _floats(n_vertices, 0, 0, quick.n_lights, False, not quick.per_light), samples) >= beat + SCREEN:
        return first
    alone = candidate(fit_lights(full, lw, exponent, alone=True, previous=quick), True)
    return alone if alone.perceptual <= first.perceptual else first


def _information(error, floats, samples):
    """An information criterion (Akaike's, with a perceptual error as the residual):
    2 ln(error) + 2 floats / samples. Lower is better: an error lower by a factor f pays
    for (ln f) x samples more floats."""
    return 2.0 * math.log(max(error, 1e-12)) + 2.0 * floats / samples


def _criterion(fit, samples):
    """``_information`` of a fitted model (a ``Components``)."""
    return _information(fit.perceptual, fit.floats, samples)


def _or_alone(kept, alone, floor, samples, target):
    """What "auto" keeps once lights alone (``_lights_alone``: None if none were fitted)
    are weighed against ``kept``, its choice among the other models: they are kept where
    they are no worse than the diffuse walkthrough and their criterion (``_criterion``)
    is the lower. Why a criterion, and not the others' rule (the cheapest within reach of
    the best): lights alone have 3 K coefficients a vertex, and fitted to the same samples
    they are measured on they draw a gather's noise too: on a diffuse colour times noise
    8 lights (9 x the floats) measured 5 % below the walkthrough's error, which the rule
    would keep. The criterion asks an error lower by a factor that pays for the floats."""
    if alone is None or _above(alone, floor) or _criterion(alone, samples) >= _criterion(kept, samples):
        return kept
    if kept.perceptual <= target and alone.floats >= kept.floats:  # the cheapest reaching the target
        return kept
    why = (f"lights alone: perceptual {alone.perceptual:.3g} with {alone.floats:,} floats, against "
           f"{_name(kept)}'s {kept.perceptual:.3g} with {kept.floats:,} (the lower information criterion)")
    return replace(alone, tried=kept.tried, baseline=kept.baseline, why=why)


def _probe_and_lights(record, full, data, rest, lw, probe_fit, probe_term, *, place, exponent, fit_lights, required):
    """Lights for what the probe leaves, then the probe again with them held, then every
    per-vertex coefficient together; probe_fit = (the chosen probe model's
    ``Components``, its probe's S P(u) at the samples); place = the probe's (centre, box,
    albedo table).

    Unless the lights are ``required`` (--model probe+lights), one light is fitted
    first (with every coefficient), and the others only if it pays: if it lowers the
    perceptual error of the probe's model by less than FIRST_LIGHT_PAYS of it, what the
    probe leaves is detail no few lights draw (a room seen in a near-mirror), and the
    lights' search, most of such an object's fit, is not run; nor where the first light
    carried nothing and was dropped (the mirror plate: 1.2 s). The one-light step is
    in what was tried, marked not kept."""
    centre, box, albedo = place
    chosen, values = probe_fit
    lights_data = FitData(radiance=np.maximum(rest - probe_term, 0.0), views=full.views, normals=full.normals,
                          weights=full.weights, positions=full.positions)
    first = None
    if not required:
        first = fit_lights(lights_data, lw, exponent, count=1)
        if first.n_lights:
            lights = (first.pos, first.rgb, first.shininess)
            columns = _light_columns(data, lights, not first.per_light)
            e, s, c = _joint(data, rest, lw, values, columns)
            one = record("probe+lights", chosen.probe.size, True, e, light_fit=(*lights, c), probe_fit=chosen.probe,
                         weight=s, probe_term=s[:, None, :] * values, light_term=columns.term(c),
                         keep=False, loss=chosen.loss)
            if chosen.perceptual - one.perceptual < FIRST_LIGHT_PAYS * chosen.perceptual:
                return
        else:  # the first light carried nothing (dropped as degenerate): nor would more
            return
    fitted = fit_lights(lights_data, lw, exponent, previous=first)
    if not fitted.n_lights:
        if required:  # nothing left for a light to explain
            record("probe+lights", chosen.probe.size, True, chosen.emitted, probe_fit=chosen.probe,
                   weight=chosen.probe_weight, probe_term=probe_term, loss=chosen.loss)
        return
    lights = (fitted.pos, fitted.rgb, fitted.shininess)
    columns = _light_columns(data, lights, not fitted.per_light)
    e, s, c = _joint(data, rest, lw, values, columns)
    light_term = columns.term(c)
    p2, _, _, values = fit_probe_part(data, rest, lw, chosen.probe.size, centre, box, albedo, fixed=light_term,
                                      start=(e, s), rounds=WARM_ROUNDS)
    e, s, c = _joint(data, rest, lw, values, columns)
    record("probe+lights", p2.size, True, e, light_fit=(*lights, c), probe_fit=p2, weight=s,
           probe_term=s[:, None, :] * values, light_term=columns.term(c), loss=chosen.loss)


def directional_mean(radiance):
    """(V, 3) float64: each vertex's radiance (V, D, 3) averaged over the directions of its
    equal-area grid: what the diffuse walkthrough draws (``display.renderer``'s mean)."""
    return np.asarray(radiance, np.float64).mean(axis=1)


def _with_tried(c, tried, full, why=""):
    mean = np.broadcast_to(directional_mean(full.radiance)[:, None, :], full.radiance.shape)
    return Components(**{**c.__dict__, "tried": tried, "baseline": relative_error(full, mean)["relative_rms"],
                         "why": why})


def _choose_loss(record, problem, weights, probe_place):
    """The loss "auto" fits an object's probes and lights with, and the first probe size's
    fit with it: (loss, (Probe, emitted, weight, values)). Both losses fit that probe
    (``weights`` gains the linear one's); the linear loss is kept where its probe's
    perceptual error is below 1 - LOSS_MARGIN times the relative one's, the relative
    loss otherwise; the other is recorded as tried, not kept. problem = (data: the rest
    as ``FitData``, the rest (V, D, 3), the whole radiance's ``FitData``, the emitters'
    term (V, D, 3)); probe_place = (size, centre, box, albedo table).

    Why: the relative loss weighs a sample by 1 / (eps + L)^2, eps 5 % of the object's
    mean, a sample near zero hundreds of times a typical one. On a clean solution it
    keeps dim reflections from drowning: the built-in scenes' linear probes are at most
    6 % below its perceptual error and look worse (the teapot's fitted display
    against the solution's, FLIP on it 0.166 / 0.124 / 0.172 -> 0.174 / 0.139 / 0.185).
    Where the gather's noise leaves many samples near zero beside bright ones, it fits
    every colour, probe and light far below the data: the living room's noisy objects'
    linear probes are 10 to 42 % lower on the 16 that take them, and nearer an
    independent solve."""
    data, rest, full, highlights = problem
    size, centre, box, albedo = probe_place
    fitted, seen = {}, {}
    for name in AUTO_LOSSES:
        if name not in weights:
            weights[name] = make_loss_weights(full, name)
        fitted[name] = fit_probe_part(data, rest, weights[name], size, centre, box, albedo)
        _, e, s, values = fitted[name]
        seen[name] = perceptual_error(full, _model(highlights, e, s[:, None, :] * values, None))
    loss = "linear" if seen["linear"] < (1 - LOSS_MARGIN) * seen["relative"] else "relative"
    other = "relative" if loss == "linear" else "linear"
    p, e, s, values = fitted.pop(other)
    record("probe", size, True, e, probe_fit=p, weight=s, probe_term=s[:, None, :] * values, keep=False, loss=other)
    return loss, fitted[loss]


def _shows_highlight(residual, full):
    """True where the residual still peaks above HIGHLIGHT x the object's mean radiance:
    a highlight the emitters and the probe do not draw (a lamp seen in a glossy neighbour)."""
    mean = float(np.sum(full.weights[:, :, None] * full.radiance) / max(full.weights.sum(), 1e-300) / 3.0)
    return bool(np.max(residual) > HIGHLIGHT * mean) if mean > 0 else False


def _above(fit, floor):
    """True if ``fit``'s perceptual error exceeds the diffuse walkthrough's (``floor``, a
    ``Components`` or None: no floor)."""
    return floor is not None and fit is not floor and fit.perceptual > floor.perceptual


def _pick(fits, target):
    """(the cheapest fit whose perceptual error reaches ``target`` or comes within WITHIN
    of the best one's, the best error)."""
    order = sorted(fits, key=lambda f: f.floats)
    best = min(f.perceptual for f in order)
    for f in order:
        if f.perceptual <= target or f.perceptual <= best * (1 + WITHIN) or math.isclose(f.perceptual, best):
            return f, best
    return order[-1], best


def _choose(fits, target, tried, full, floor=None, reason="", unfloored=None):
    """Error per stored float (``_pick``), among the ``fits`` no worse than the diffuse
    walkthrough (``floor``: the "diffuse" candidate, kept when no fit is eligible); the
    kept one says why (``Components.why``), and whether the floor changed the choice:
    what would be kept without it (``_pick`` of ``unfloored``, default ``fits``)."""
    eligible = [f for f in fits if not _above(f, floor)] or [floor]
    chosen, best = _pick(eligible, target)
    without, _ = _pick(fits if unfloored is None else unfloored, target)
    return _with_tried(chosen, tried, full, _why(chosen, without, (target, best), floor, tried, reason))


def _name(fit):
    """How the report names a fitted model: "probe 32 4L, linear loss"."""
    return (fit.model + (f" {fit.probe.size}" if fit.probe is not None else "")
            + (f" {fit.n_lights}L" if fit.n_lights else "") + (f", {fit.loss} loss" if fit.loss else ""))


def _why(chosen, without, bounds, floor, tried, reason):
    """One line: why "auto" kept ``chosen`` (``Components.why``), ``without`` what it
    would keep without the floor; bounds = (the target, the best eligible error)."""
    target, best = bounds
    others = [t for t in tried if t.get("kept", True) and t["model"] != "diffuse"]
    if floor is not None and chosen is floor and others and all(t.get("above_floor") for t in others):
        return (f"kept diffuse: every other model was worse (perceptual {min(t['perceptual'] for t in others):.3g} "
                f"at best, the diffuse walkthrough's {floor.perceptual:.3g})")
    if chosen.perceptual <= target:
        why = f"the cheapest reaching the target {target:g}"
    elif math.isclose(chosen.perceptual, best):
        why = "the best"
    else:
        why = f"the cheapest within {WITHIN:.0%} of the best ({best:.3g})"
    if reason:
        why = f"{reason}; {why}"
    if without is not chosen:
        why += (f"; not {_name(without)} (perceptual {without.perceptual:.3g}): worse than the diffuse walkthrough "
                f"({floor.perceptual:.3g})")
    return why
