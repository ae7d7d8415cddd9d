"""Virtual lights of either kind, with shared or per-light coefficients, fitted by
variable projection (beyond the paper: its section 4.1 names both extensions).

A light is ``pos = (x, y, z, w)`` (OpenGL's GL_POSITION): w = 0 a distant light in the
unit direction xyz, w = 1 a point light at xyz; at vertex x its light vector is
l = normalize(xyz - w x). A near lamp's highlight moves across a curved object in a way
no distant light reproduces; a distant light stays directional (three numbers fewer).

The model of one object (fit.npz, version 2):

    shared     L(v, w) ~ e_v + s_v * sum_k rgb_k lobe_k(v, w)          (the paper's)
    per-light  L(v, w) ~ e_v + sum_k c_vk lobe_k(v, w)                   (rgb_k = 1)

with lobe_k(v, w) = max(0, n_v . normalize(l_k(x_v) + w))^p_k (``fitting.lobes``). The
per-vertex coefficients (e, s or c, per channel, non-negative and capped) are linear
given the lights, so every evaluation of the objective solves them exactly (small
bounded least-squares problems, ``fitting.nnls``) and the gradient with respect to the
lights is the partial one at those coefficients (variable projection).

Where a light goes (``seed``): at the largest residual of the current model, the mirror
ray of that view about that vertex's normal points at what makes the highlight. The
solution's own geometry says what the ray hits (``seeds.first_hits``) and the mirror
rays of the other vertices that see the same highlight meet near it
(``seeds.meeting_point``): a point light there; a ray that meets nothing makes a
directional light. Each light added is polished with the others by a short
refinement before the next; at the end all are refined together.

Kinds (``light_kind``): "directional", "positional", or "auto": each point light is
tried as a distant light in the direction it has from the object's centre and becomes
one when that leaves the error within ``AUTO_TOLERANCE`` (a distant light is the same
model with three numbers fewer).

Degenerate lights: a light that carries (almost) nothing, or duplicates another, is
re-seeded at the largest residual and the fit refined again; if it still carries
nothing it is dropped.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import minimize

from .lobes import Samples, mixed_light_sum, mixed_loss_and_gradient, normal_equations
from .model import light_vectors
from .nnls import solve_many
from .options import LIGHT_KINDS
from .results import Lights, LightsFit
from .seeds import first_hits, meeting_point, mirror

KINDS = LIGHT_KINDS
CAP_FACTOR = 8.0  # as paper.CAP_FACTOR: a vertex's highlight stays below 8x its brightest sample
AUTO_TOLERANCE = 0.005  # "auto": a point light becomes directional if the error grows less than this (relative)
USELESS = 1e-4  # a light whose part of the model has less than this fraction of the data's energy carries nothing
DUPLICATE_LOBE = 0.25  # two lights of a kind closer than this fraction of their lobe's width (1 / sqrt(p + 1) rad) are one
POLISH_ITERATIONS = 4
STOP = threading.Event()  # set: every refinement running in a thread of this process stops at its next evaluation
PLACEMENT_SAMPLES = 1 << 16  # lights are placed on every k-th vertex of a larger object, about this many samples, then refined on all
MEETING_RAYS = 256  # the strongest vertices whose mirror rays locate a light
FAR = 1e4  # a point light with nothing to locate it starts this many object sizes away
FIRST_POLISH_ITERATIONS = 12
NEAR_LOBES = 3.0  # "auto" does not try as distant a point light whose direction swings this many lobe widths
SPREAD = 4  # point lights spread over an emitter a mirror ray hits (per-light coefficients)
SPREAD_SHARPENING = 0.35  # their exponent: the single light's times count^this (measured: 1, 4, 9 lights ~ 230, 360, 470)


@dataclass(frozen=True, eq=False)
class SceneGeometry:
    """The whole scene as seeds see it: triangles (T, 3, 3) world space (float32 when the
    meshes' positions are, as a solution's are: half the memory, in every fitting
    process, and the same values), the object of each (T,) int, and which objects emit
    (n_objects,) bool."""

    triangles: np.ndarray
    triangle_object: np.ndarray
    emissive: np.ndarray

    @classmethod
    def empty(cls):
        return cls(np.zeros((0, 3, 3)), np.zeros(0, np.int64), np.zeros(0, bool))

    @classmethod
    def of_solution(cls, solution):
        """From a ``radiosity.files.solution.Solution``: every object's triangles; emitters are
        the objects whose material emits."""
        return cls.of_meshes((o.positions, o.faces, o.material) for o in solution.objects)

    @classmethod
    def of_meshes(cls, meshes):
        """From (positions (V, 3), faces (F, 3), material dict) of every object, in order."""
        meshes = [(np.asarray(p), np.asarray(f), m) for p, f, m in meshes]
        dtype = np.float32 if all(p.dtype == np.float32 for p, _, _ in meshes) else np.float64
        total = sum(len(f) for _, f, _ in meshes)
        tris = np.empty((total, 3, 3), dtype)
        owner = np.empty(total, np.int32 if len(meshes) < 2**31 else np.int64)
        at = 0
        for i, (positions, faces, _) in enumerate(meshes):  # filled in place: no second copy of the scene
            tris[at:at + len(faces)] = positions.astype(dtype, copy=False)[faces]
            owner[at:at + len(faces)] = i
            at += len(faces)
        return cls(tris, owner, np.array([max(m["emission"]) > 0 for _, _, m in meshes], bool))

    def spread(self, obj, count, seed=0):
        """``count`` points spread evenly over object ``obj``'s area (k-means of its
        triangles' centroids, each repeated by area): where several point lights stand
        in for one area light."""
        from scipy.cluster.vq import kmeans2

        tri = self.triangles[self.triangle_object == obj].astype(np.float64)
        centroids = tri.mean(axis=1)
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        if len(centroids) <= count:
            return centroids
        repeat = np.maximum(1, np.round(area / max(area[area > 0].min() if (area > 0).any() else 1.0, 1e-300)).astype(int))
        points = np.repeat(centroids, np.minimum(repeat, 16), axis=0)
        centres, _ = kmeans2(points, count, minit="++", seed=seed)
        return centres


@dataclass(frozen=True, eq=False)
class Problem:
    """What stays fixed while one object is fitted.

    data: the ``FitData``; samples: its ``Samples``; per_light: the coefficient model;
    centre (3,), size: the object's bounding-box centre and half diagonal;
    scene: the whole scene's ``SceneGeometry``, for seeds; exponent_bounds
    """

    data: object
    samples: Samples
    per_light: bool
    centre: np.ndarray
    size: float
    scene: SceneGeometry
    exponent_bounds: tuple[float, float]
    brightest: np.ndarray  # (V, 3) each vertex's brightest sample (the coefficients' caps)
    energy: float  # sum w |L|^2 (with the loss weights): the error of the empty model

    @property
    def triangles(self):
        return self.scene.triangles

    def subset(self, step):
        """The same problem on every ``step``-th vertex (weights renormalised): where the
        greedy placement polishes its lights before the full refinement."""
        idx = np.arange(0, self.data.n_vertices, step)
        data = self.data.vertices(idx)
        total = data.weights.sum()
        data = replace(data, weights=data.weights / total) if total > 0 else data
        lw = self.samples.loss_weights
        lw = lw if lw.shape[0] == 1 else np.ascontiguousarray(lw[idx])
        return Problem.make(data, None if lw.shape[0] == 1 else lw, self.per_light, self.scene, self.exponent_bounds)

    @classmethod
    def make(cls, data, loss_weights, per_light, scene, exponent_bounds):
        lw = np.ones((1, 1, 1)) if loss_weights is None else np.ascontiguousarray(loss_weights, np.float64)
        positions = np.ascontiguousarray(data.positions, np.float64)
        lo, hi = positions.min(axis=0), positions.max(axis=0)
        size = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-12)
        samples = Samples(positions, np.ascontiguousarray(data.radiance), np.ascontiguousarray(data.weights), lw)
        scene = SceneGeometry.empty() if scene is None else scene
        energy = float(np.sum(data.weights[:, :, None] * lw * data.radiance**2))
        return cls(data, samples, per_light, 0.5 * (lo + hi), size, scene, tuple(exponent_bounds),
                   data.radiance.max(axis=1), energy)


def coefficients(problem, lights):
    """The optimal per-vertex coefficients for these lights: (emitted (V, 3),
    specular (V, 3) or (V, K, 3), weighted squared error)."""
    data = problem.data
    n_v, n_k = data.n_vertices, len(lights.pos)
    n = n_k + 1 if problem.per_light else 2
    G = np.empty((n_v, 3, n, n))
    h = np.empty((n_v, 3, n))
    yy = np.empty((n_v, 3))
    normal_equations(data.normals, data.views, lights, problem.samples, problem.per_light, G, h, yy)
    # caps: over every view of the hemisphere a lobe peaks at 1 if its light is above the
    # horizon, else at the grazing view opposite it (half-vector angle (theta - 90) / 2)
    unit = light_vectors(lights.pos, problem.samples.positions)  # (V, K, 3)
    cos_theta = np.clip(np.einsum("vi,vki->vk", data.normals, unit), -1.0, 1.0)
    theta = np.arccos(cos_theta)
    peak = np.cos(np.maximum(theta - np.pi / 2, 0.0) / 2) ** lights.shininess[None, :]  # (V, K)
    brightest = problem.brightest
    cap = np.full((n_v, 3, n), np.inf)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        if problem.per_light:
            shown = peak[:, None, :] * lights.rgb.T[None, :, :]  # (V, 3, K)
            cap[:, :, 1:] = np.where(shown > 0, CAP_FACTOR * brightest[:, :, None] / shown, 0.0)
        else:
            shown = np.max(peak[:, None, :] * lights.rgb.T[None, :, :], axis=2) if n_k else np.zeros((n_v, 3))
            cap[:, :, 1] = np.where(shown > 0, CAP_FACTOR * brightest / shown, 0.0)
    cap = np.minimum(cap, 1e200)
    x = solve_many(G.reshape(-1, n, n), h.reshape(-1, n), cap.reshape(-1, n), np.zeros((n_v * 3, n))).reshape(n_v, 3, n)
    err = yy - 2 * np.einsum("vci,vci->vc", h, x) + np.einsum("vci,vcij,vcj->vc", x, G, x)
    emitted = x[:, :, 0]
    specular = np.ascontiguousarray(np.transpose(x[:, :, 1:], (0, 2, 1))) if problem.per_light else x[:, :, 1]
    return emitted, specular, float(np.maximum(err, 0.0).sum())


def model_colours(problem, lights, emitted, specular):
    """The model at the data's samples (V, D, 3)."""
    data = problem.data
    coef = specular if specular.ndim == 3 else specular[:, None, :]
    out = np.empty_like(data.radiance)
    mixed_light_sum(data.normals, data.views, lights, problem.samples, np.ascontiguousarray(coef, np.float64), out)
    return out + emitted[:, None, :]


def evaluate(problem, pos, rgb, shininess):
    """A ``LightsFit`` with the optimal coefficients for these lights (with per-light
    coefficients the lights' colours are ones: the coefficients carry the colour)."""
    if problem.per_light:
        rgb = np.ones((len(np.reshape(pos, (-1, 4))), 3))
    lights = Lights.of(pos, rgb, shininess)
    e, s, err = coefficients(problem, lights)
    return LightsFit(*lights, e, s, err)


def no_lights(problem):
    """The model without lights: the best emitted colour per vertex."""
    return evaluate(problem, np.zeros((0, 4)), np.zeros((0, 3)), np.zeros(0))


@dataclass(frozen=True, eq=False)
class Parameters:
    """x = per light: position (3: a raw direction, normalised, for a distant light; the
    offset from the object's centre over its size for a point light), then colours over
    ``scale`` (3K, shared coefficients only), then log exponents (1 or K)."""

    kinds: np.ndarray  # (K,) w of each light
    per_light_exponents: bool
    fit_rgb: bool
    scale: float
    centre: np.ndarray
    size: float

    @property
    def n_lights(self):
        return len(self.kinds)

    def pack(self, fit):
        xyz = fit.pos[:, :3].copy()
        point = self.kinds == 1
        xyz[point] = (xyz[point] - self.centre) / self.size
        logp = np.log(fit.shininess if self.per_light_exponents else fit.shininess[:1])
        parts = [xyz.ravel()] + ([fit.rgb.ravel() / self.scale] if self.fit_rgb else []) + [logp]
        return np.concatenate(parts)

    def unpack(self, x, rgb_fixed):
        n_k = self.n_lights
        raw = x[: 3 * n_k].reshape(n_k, 3)
        point = self.kinds == 1
        norm = np.linalg.norm(raw, axis=1, keepdims=True)
        xyz = np.where(point[:, None], self.centre + raw * self.size, raw / np.where(norm > 0, norm, 1.0))
        offset = 3 * n_k
        if self.fit_rgb:
            rgb = x[offset: offset + 3 * n_k].reshape(n_k, 3) * self.scale
            offset += 3 * n_k
        else:
            rgb = rgb_fixed
        shininess = np.exp(np.broadcast_to(x[offset:], (n_k,)))
        pos = np.concatenate([xyz, self.kinds[:, None].astype(np.float64)], axis=1)
        return Lights.of(pos, rgb, shininess), norm

    def bounds(self, exponent_bounds):
        n_k = self.n_lights
        log_lo, log_hi = math.log(exponent_bounds[0]), math.log(exponent_bounds[1])
        n_p = n_k if self.per_light_exponents else 1
        rgb = [(0.0, None)] * (3 * n_k) if self.fit_rgb else []
        return [(None, None)] * (3 * n_k) + rgb + [(log_lo, log_hi)] * n_p


def objective(problem, params, rgb_fixed, x):
    """The reduced objective at x and its gradient (variable projection)."""
    lights, norm = params.unpack(x, rgb_fixed)
    e, s, _ = coefficients(problem, lights)
    coef = np.ascontiguousarray(s if s.ndim == 3 else s[:, None, :])
    partial = np.zeros((problem.data.n_vertices, params.n_lights, 7))
    loss = mixed_loss_and_gradient(problem.data.normals, problem.data.views, lights, problem.samples, e, coef, partial)
    g = partial.sum(axis=0)
    g_xyz = g[:, 4:7].copy()
    point = params.kinds == 1
    dirs = lights.pos[:, :3]
    radial = np.sum(g_xyz * dirs, axis=1, keepdims=True)
    g_dir = (g_xyz - radial * dirs) / np.where(norm > 0, norm, 1.0)
    g_xyz = np.where(point[:, None], g_xyz * params.size, g_dir)
    parts = [g_xyz.ravel()]
    if params.fit_rgb:
        parts.append((g[:, 0:3] * params.scale).ravel())
    parts.append(g[:, 3] if params.per_light_exponents else np.array([g[:, 3].sum()]))
    return loss, np.concatenate(parts)


def refine(problem, start, *, per_light_exponents=False, max_iterations=50):
    """Refine every light of ``start`` (a ``LightsFit``) jointly; returns a ``LightsFit``."""
    if start.n_lights == 0 or max_iterations <= 0:
        return start
    params = Parameters(
        kinds=start.pos[:, 3].copy(), per_light_exponents=per_light_exponents, fit_rgb=not problem.per_light,
        scale=float(np.max(start.rgb)) or 1.0, centre=problem.centre, size=problem.size,
    )
    clipped = replace(start, shininess=np.clip(start.shininess, *problem.exponent_bounds))
    if not per_light_exponents:
        clipped = replace(clipped, shininess=np.full(start.n_lights, np.exp(np.mean(np.log(clipped.shininess)))))
    x0 = params.pack(clipped)
    evaluations = 0

    # the optimiser sees the error relative to the data's energy: its tolerances then
    # mean the same for radiance 1e-8 and 1e8
    norm = 1.0 / problem.energy if problem.energy > 0 else 1.0

    def counted(x):
        nonlocal evaluations
        if STOP.is_set():  # the fit was interrupted (a Ctrl-C in the thread that started this one)
            raise KeyboardInterrupt
        evaluations += 1
        loss, grad = objective(problem, params, start.rgb, x)
        return loss * norm, grad * norm

    f0 = counted(x0)[0]
    result = minimize(counted, x0, jac=True, method="L-BFGS-B", bounds=params.bounds(problem.exponent_bounds),
                      options={"maxiter": max_iterations, "ftol": 1e-10, "gtol": 1e-12})
    x = result.x if result.fun <= f0 else x0
    lights, _ = params.unpack(x, start.rgb)
    fit = evaluate(problem, lights.pos, lights.rgb, lights.shininess)
    return replace(fit, iterations=int(result.nit), evaluations=evaluations)


def residual(problem, fit):
    return problem.data.radiance - model_colours(problem, fit.lights(), fit.emitted, fit.specular)


def seed(problem, fit, light_kind, shininess, taken=()):
    """A new light at the largest residual of ``fit``: (pos (4,), rgb (3,), the sample
    (v, d), the object its mirror ray hits or -1), or None when nothing is left to
    explain. ``taken``: (v, d) samples already used as seeds."""
    data = problem.data
    r = residual(problem, fit)
    # the residual as the loss sees it (linear: as is; relative: over the radiance)
    lw = problem.samples.loss_weights
    score = (r * np.sqrt(lw)).sum(axis=2) * np.sqrt(data.weights / data.weights.mean())
    for v, d in taken:
        score[v, d] = -np.inf
    v, d = np.unravel_index(np.argmax(score), score.shape)
    if not score[v, d] > 0:
        return None
    x = problem.samples.positions[v]
    m = mirror(data.normals[v], data.views[v, d])
    rgb = np.ones(3) if problem.per_light else np.maximum(r[v, d], 0.0) / max(float(np.max(fit.specular[v])) if fit.n_lights else 1.0, 1.0)
    if light_kind == "directional":
        return np.append(m, 0.0), rgb, (v, d), -1
    t, tri = first_hits(x[None], m[None], problem.triangles, t_min=1e-4 * problem.size)
    hit = np.isfinite(t[0])
    hit_object = int(problem.scene.triangle_object[tri[0]]) if hit else -1
    # the vertices that see a highlight as strong: the mirror rays of their own largest residual
    peak_d = np.argmax(score, axis=1)
    peak = score[np.arange(len(score)), peak_d]
    strong = np.flatnonzero(peak > 0.5 * score[v, d])
    strong = strong[np.argsort(-peak[strong])[:MEETING_RAYS]]
    rays = mirror(data.normals[strong], data.views[strong, peak_d[strong]])
    origins = problem.samples.positions[strong]
    if hit:
        point = x + t[0] * m
        # of those, the rays pointing near the hit meet near the light
        to_point = point - origins
        dist = np.linalg.norm(to_point, axis=1)
        aligned = np.einsum("ni,ni->n", rays, to_point) / np.maximum(dist, 1e-300) > math.cos(math.radians(10))
        if np.count_nonzero(aligned) >= 3:
            meet, _ = meeting_point(origins[aligned], rays[aligned], peak[strong][aligned])
            if meet is not None and np.linalg.norm(meet - point) < 0.5 * t[0]:
                point = meet
        return np.append(point, 1.0), rgb, (v, d), hit_object
    # nothing in the scene there: where the rays meet, if they do (a point light the
    # solution does not hold as geometry); parallel rays say the light is distant
    meet, _ = meeting_point(origins, rays, peak[strong]) if len(strong) >= 3 else (None, 0.0)
    if meet is not None:
        return np.append(meet, 1.0), rgb, (v, d), -1
    if light_kind == "positional":  # far away along the ray
        return np.append(x + FAR * problem.size * m, 1.0), rgb, (v, d), -1
    return np.append(m, 0.0), rgb, (v, d), -1


def _light_energy(problem, fit, k):
    """sum w |part of the model due to light k|^2 (loss-weighted)."""
    lights = fit.lights()
    one = Lights.of(lights.pos[k: k + 1], lights.rgb[k: k + 1], lights.shininess[k: k + 1])
    coef = fit.specular[:, k: k + 1, :] if fit.per_light else fit.specular[:, None, :]
    out = np.empty_like(problem.data.radiance)
    mixed_light_sum(problem.data.normals, problem.data.views, one, problem.samples, np.ascontiguousarray(coef), out)
    return float(np.sum(problem.data.weights[:, :, None] * problem.samples.loss_weights * out**2))


def degenerate_lights(problem, fit):
    """Indices of lights that carry nothing or duplicate an earlier one."""
    energy = problem.energy
    bad = []
    for k in range(fit.n_lights):
        if _light_energy(problem, fit, k) < USELESS * energy:
            bad.append(k)
            continue
        for j in range(k):
            if j in bad or fit.pos[j, 3] != fit.pos[k, 3]:
                continue
            width = DUPLICATE_LOBE / math.sqrt(max(fit.shininess[j], fit.shininess[k]) + 1.0)
            if fit.pos[k, 3] == 0:
                same = math.acos(np.clip(np.dot(fit.pos[j, :3], fit.pos[k, :3]), -1, 1)) < width
            else:
                # seen from the object's centre: the same direction and about the same distance
                a, b = fit.pos[j, :3] - problem.centre, fit.pos[k, :3] - problem.centre
                same = np.linalg.norm(a - b) < width * max(np.linalg.norm(a), np.linalg.norm(b), problem.size)
            if same and abs(math.log(fit.shininess[j] / fit.shininess[k])) < 0.1:
                bad.append(k)
                break
    return bad


def _without(fit, drop):
    keep = np.setdiff1d(np.arange(fit.n_lights), drop)
    return fit.pos[keep], fit.rgb[keep], fit.shininess[keep]


def to_directional(problem, fit):
    """"auto": each point light that a distant light replaces within AUTO_TOLERANCE of the
    error becomes one (the direction it has from the object's centre)."""
    for k in np.flatnonzero(fit.pos[:, 3] == 1):
        pos = fit.pos.copy()
        d = pos[k, :3] - problem.centre
        norm = np.linalg.norm(d)
        if norm == 0:
            continue
        if problem.size / norm > NEAR_LOBES / math.sqrt(fit.shininess[k] + 1.0):
            continue  # its direction swings across the object by several lobe widths: it is near
        pos[k] = np.append(d / norm, 0.0)
        trial = evaluate(problem, pos, fit.rgb, fit.shininess)
        if trial.sq_error <= fit.sq_error * (1 + AUTO_TOLERANCE) + 1e-300:
            fit = replace(trial, iterations=fit.iterations, evaluations=fit.evaluations)
    return fit


def fit_mixed(problem, n_lights, shininess, *, light_kind="auto", per_light_exponents=False, iterations=50,
              previous=None, log=None):
    """K lights by greedy seeding, each polished with the others, then refined jointly.

    shininess: the starting exponent; previous: a ``LightsFit`` with fewer lights to
    continue from. Returns a ``LightsFit`` with at most ``n_lights`` lights.
    """
    full = problem
    samples = problem.data.n_vertices * problem.data.n_directions
    if samples > 2 * PLACEMENT_SAMPLES and problem.data.n_vertices >= 4:
        # lights are placed and polished on a subset of the vertices, refined on all
        problem = full.subset(min(int(math.ceil(samples / PLACEMENT_SAMPLES)), problem.data.n_vertices // 2))
    if previous is not None:
        fit = evaluate(problem, previous.pos, previous.rgb, previous.shininess)
    else:
        fit = no_lights(problem)
    taken = []
    spread = set()
    polish = min(POLISH_ITERATIONS, iterations)
    while fit.n_lights < n_lights:
        new = seed(problem, fit, light_kind, shininess, taken)
        if new is None:
            break
        pos, rgb, sample, hit = new
        taken.append(sample)
        p = shininess if not fit.n_lights else float(np.exp(np.mean(np.log(fit.shininess))))
        pos, rgb, p = [pos], [rgb], [p]
        if problem.per_light and hit >= 0 and problem.scene.emissive[hit] and hit not in spread:
            # an emitter: its highlight is an area light's; several point lights over its
            # area, each with its own coefficients, draw it (one light draws a blur)
            count = min(n_lights - fit.n_lights, SPREAD)
            spread.add(hit)
            if count > 1:
                pos = [np.append(c, 1.0) for c in problem.scene.spread(hit, count)]
                count = len(pos)  # an emitter of fewer triangles than count gets one light on each
                rgb = [rgb[0]] * count
                p = [p[0] * count**SPREAD_SHARPENING] * count
        first = fit.n_lights == 0
        trial = evaluate(problem, np.vstack([fit.pos, *pos]), np.vstack([fit.rgb, *rgb]), np.append(fit.shininess, p))
        # the first light settles the exponent (it starts from a guess): polish it longer
        fit = refine(problem, trial, per_light_exponents=per_light_exponents,
                     max_iterations=max(polish, FIRST_POLISH_ITERATIONS) if first else polish)
        if log is not None:
            log(fit)
    problem = full
    fit = evaluate(problem, fit.pos, fit.rgb, fit.shininess)
    fit = refine(problem, fit, per_light_exponents=per_light_exponents, max_iterations=max(iterations - polish, 0))
    # lights that carry nothing or duplicate another: seed them again where the error is
    for _ in range(2):
        bad = degenerate_lights(problem, fit)
        if not bad:
            break
        pos, rgb, shin = _without(fit, bad)
        reduced = evaluate(problem, pos, rgb, shin)
        for _ in bad:
            new = seed(problem, reduced, light_kind, shininess, taken)
            if new is None:
                break
            taken.append(new[2])
            p = float(np.exp(np.mean(np.log(reduced.shininess)))) if reduced.n_lights else shininess
            reduced = evaluate(problem, np.vstack([reduced.pos, new[0]]), np.vstack([reduced.rgb, new[1]]),
                               np.append(reduced.shininess, p))
        fit = refine(problem, reduced, per_light_exponents=per_light_exponents, max_iterations=max(iterations // 2, polish))
    bad = degenerate_lights(problem, fit)
    if bad:
        pos, rgb, shin = _without(fit, bad)
        fit = replace(evaluate(problem, pos, rgb, shin), iterations=fit.iterations, evaluations=fit.evaluations)
    if light_kind == "auto":
        fit = to_directional(problem, fit)
    return fit
