"""The fitting stage: ``fit(solution, options) -> FittedModel`` (fit.npz, docs/formats.md).

Per object, one path (``fit_object``): glass and perfect mirrors are not fitted (the
displays draw what they show); diffuse objects keep their radiance as the emitted
colour and get no lights; every glossy object goes through ``fitting.glossy``, whatever
its model: the emitters' term, a reflection probe and virtual lights, chosen by
``--model auto`` or asked for, the paper's lights alone (``--model lights``, ``--method
paper``) included (their lights: ``fitting.lights``). One record says what was fitted
(``_record``: the object's ``info`` in fit.npz).
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import replace

import numpy as np

from radiosity.files.solution import SolutionFile
from radiosity.physics.materials import NEAR_MIRROR_ALPHA, Microfacet, near_base

from . import glossy, mixed
from .data import fit_data, relative_error
from .lights import LightFitter, start_exponent
from .memory import cores, costs
from .model import FittedModel, FittedObject, Highlight, Mirror
from .options import COEFFICIENTS, LIGHT_KINDS, METHODS, MODELS, FitOptions, quality_of  # noqa: F401 (the fit's words)
from .results import Lights

ONE_OBJECT_SHARE = 0.5  # no worker processes when one glossy object has more than this share of the samples
NO_LIGHTS = Lights.none()  # a glass, mirror or diffuse object's


def _json_number(value):
    """A float for the file's meta, None where it is not finite (strict JSON)."""
    value = float(value)
    return value if math.isfinite(value) else None


def fit_object(obj, options, scene=None, progress=None, solution=None, box=None):
    """FittedObject for one ``ObjectSolution``; ``scene`` the ``mixed.SceneGeometry`` of
    the whole solution (where point lights are seeded); ``progress`` a tqdm bar or None;
    ``solution`` (its emitters) and ``box`` (the probe's proxy) for the models with emitters and a probe.
    A glass object or a perfect mirror is not fitted: the displays draw what it shows
    (``display.glass``, ``display.mirror``)."""
    material = obj.material_record
    if material.is_glass or material.is_mirror:
        zeros = np.zeros((obj.num_vertices, 3))
        kind = "glass" if material.is_glass else "mirror"
        info = {"model": kind, "method": "none", "time_s": 0.0,
                "chosen_by": f"{material.glass.kind if material.is_glass else 'a perfect mirror'}: drawn as {kind}"}
        mirror = None if material.is_glass else Mirror(material.specular, material.fresnel)
        return replace(_fitted_object(obj, zeros, zeros, NO_LIGHTS, info),
                       glass=material.glass, mirror=mirror, textured=None)
    if obj.is_diffuse:
        return _diffuse_object(obj, options)
    return _glossy_object(obj, options, scene, progress, solution, box)


def _diffuse_object(obj, options):
    """A diffuse object: its one radiance per vertex, no lights."""
    t0 = time.perf_counter()
    data = fit_data(obj)
    emitted = data.radiance[:, 0, :]
    error = relative_error(data, np.broadcast_to(emitted[:, None, :], data.radiance.shape))
    info = {
        "model": "diffuse", "method": "diffuse", "loss": options.loss_for("lights"), "chosen_by": "diffuse: no lights",
        "coefficients": "none", "kinds": [], "shininess": [],
        "error": {
            "relative_rms": _json_number(error["relative_rms"]),
            "worst_vertex": _json_number(error["worst_vertex"]),
            "worst_vertex_index": error["worst_vertex_index"],
            "diffuse_only_relative_rms": _json_number(error["relative_rms"]),
            "diffuse_only_worst_vertex": _json_number(error["worst_vertex"]),
        },
        "time_s": round(time.perf_counter() - t0, 4),
    }
    return _fitted_object(obj, emitted, np.zeros_like(emitted), NO_LIGHTS, info)


def _glossy_object(obj, options, scene, progress, solution, box):
    """A glossy object's model, whatever it is made of (``fitting.glossy.fit_components``:
    the emitters' term, a probe, virtual lights; the paper's lights alone included)."""
    t0 = time.perf_counter()
    log = None
    if progress is not None:
        def log(fit):
            progress.set_postfix_str(f"{obj.name}: {fit.n_lights} lights", refresh=True)
    lights = LightFitter(options, scene, log)
    alone = options.glossy_model == "lights"  # the paper's model: no emitter term, no probe
    if solution is None and not alone:
        raise ValueError("the models with emitters and a probe need the solution (its emitters)")
    own = () if alone else solution.parts_of(obj.name)  # the parts its highlight draws (the object's own, or all)
    parts = len(own) if obj.visibility is not None else 0
    c = glossy.fit_components(obj, lambda vertices: solution.highlights(obj.name, vertices), parts, options, scene,
                              box, start_exponent(obj, options), lights, probe_sizes=options.probe_sizes,
                              search_samples=options.search_samples, block_samples=options.block_samples)
    highlight = None
    if c.emitters and parts:
        m = obj.material_record
        indices = None if obj.emitter_parts is None else tuple(int(i) for i in obj.emitter_parts)
        lobe = solution.lobe_of(obj.name)
        highlight = Highlight(tuple(own), solution.emitter_nodes, np.asarray(m.specular, np.float64),
                              float(m.exponent), np.asarray(obj.visibility, np.float32),
                              None if m.fresnel is None else np.asarray(m.fresnel, np.float64), indices,
                              None if lobe is None else Microfacet.from_dict(lobe))
    specular = c.specular if c.n_lights or alone else np.zeros((obj.num_vertices, 3))
    weight = None if c.probe is None else np.asarray(c.probe_weight, np.float32)
    return _fitted_object(obj, c.emitted, specular, c.lights, _record(c, options, lights.chosen_by, t0),
                          highlight=highlight, probe=c.probe, probe_weight=weight)


def _record(c, options, chosen_by, t0):
    """The one record of what was fitted to a glossy object (its ``info`` in fit.npz):
    the model, how it was chosen, its lights, its errors, what "auto" tried."""
    per_light = c.n_lights and c.specular.ndim == 3
    if c.chosen_by:  # the model "lights" asked for: how its count was chosen
        how = c.chosen_by
    else:
        how = ("--model " + options.model) + (f"; lights: {chosen_by[-1]}" if chosen_by and c.n_lights else "")
    error = {"relative_rms": _json_number(c.error)}
    if c.worst:
        error |= {"worst_vertex": _json_number(c.worst["worst_vertex"]), "worst_vertex_index": c.worst["worst_vertex_index"]}
    error |= {"perceptual": _json_number(c.perceptual), "diffuse_only_relative_rms": _json_number(c.baseline)}
    if c.worst:
        error["diffuse_only_worst_vertex"] = _json_number(c.worst["diffuse_only_worst_vertex"])
    info = {
        "model": c.model,
        "method": options.method,
        "loss": c.loss or "none",
        "chosen_by": how,
        "coefficients": ("per-light" if c.specular.ndim == 3 else "shared") if c.chosen_by
        else "per-light" if per_light else ("shared" if c.n_lights else "none"),
        "kinds": ["positional" if w == 1 else "directional" for w in np.asarray(c.lights[0])[:, 3]],
        "shininess": [round(float(p), 4) for p in c.lights[2]],
        "error": error,
        "floats": int(c.floats),
        "tried": c.tried,
        **({"why_kept": c.why} if c.why else {}),
        "time_s": round(time.perf_counter() - t0, 4),
    }
    if c.iterations:
        info["iterations"] = c.iterations
    return info


def _fitted_object(obj, emitted, specular, lights, info, **parts):
    """The FittedObject of solution object ``obj``: its mesh, these coefficients and
    lights (a ``results.Lights``: pos, rgb, shininess), and the version-3 ``parts`` (highlight, probe, weight);
    a textured object's diffuse term is carried as the solution has it (version 4)."""
    pos, rgb, shininess = lights
    near = _near(obj)
    if near is not None:
        parts = {**parts, "near_base": near[0].astype(np.float32),
                 "near_microfacet": obj.material_record.microfacet}
    return FittedObject(
        name=obj.name,
        positions=np.asarray(obj.positions, np.float32),
        normals=np.asarray(obj.normals, np.float32),
        faces=np.asarray(obj.faces, np.int32),
        emitted=np.asarray(emitted, np.float32),
        specular=np.asarray(specular, np.float32),
        light_pos=np.asarray(pos, np.float32).reshape(-1, 4),
        light_rgb=np.asarray(rgb, np.float32).reshape(-1, 3),
        shininess=np.asarray(shininess, np.float32).reshape(-1),
        info=info,
        textured=obj.textured,
        **parts,
    )


NEAR_CHUNK_VALUES = 1 << 22  # a near mirror's grid is read this many values at a time


def _near(obj):
    """A near mirror's own part (``radiosity.physics.materials.near_base``: (base (V, 3), eta))
    for a glossy solution object of a microfacet material at most ``NEAR_MIRROR_ALPHA`` rough,
    which a display may draw as one (flat ones: ``display.mirror``), else None. From the
    solution's grid, a chunk of vertices at a time."""
    model = obj.material_record.microfacet
    if model is None or obj.is_diffuse or model.alpha > NEAR_MIRROR_ALPHA:
        return None
    radiance = obj.radiance
    step = max(1, NEAR_CHUNK_VALUES // max(radiance.shape[1], 1))

    def reduce(function):
        return np.concatenate([function(np.asarray(radiance[i:i + step], np.float64))
                               for i in range(0, len(radiance), step)])

    return near_base(model, obj.directions, reduce)


def fit(solution, options=None, progress=False, workers=1, client=None):
    """The fitted model of every object of ``solution``: a ``Solution``, or a
    ``radiosity.files.solution.SolutionFile``, read an object at a time so that the
    fit's memory is that of the objects being fitted, not of the whole solution.
    ``options`` None: ``FitOptions.for_quality`` of the quality the solution was solved
    at (``quality_of``), as ``vlights fit`` with no flag.
    ``workers`` > 1 (a ``SolutionFile`` only) fits the glossy objects in that many
    processes, the costliest first (in that many threads of this process where
    ``planned_workers`` starts none: one object is most of the work); ``client`` (a ``distributed.Client``, a
    ``SolutionFile`` only) fits them as Dask tasks instead (``fitting.cluster``). The
    model is the same, bit for bit, whichever runs it."""
    options = FitOptions.for_quality(quality_of(solution)[0]) if options is None else options.check()
    streamed = isinstance(solution, SolutionFile)
    if (workers > 1 or client is not None) and not streamed:
        raise ValueError("workers > 1 or a Dask client needs a SolutionFile (objects are read from the file one at a time)")
    if streamed:
        meshes = [(*solution.geometry(n), solution.materials[n]) for n in solution.names]
        scene = mixed.SceneGeometry.of_meshes(meshes)
        box = glossy.proxy_box_of(m[0] for m in meshes)
        del meshes
    else:
        scene = mixed.SceneGeometry.of_solution(solution)
        box = glossy.proxy_box(solution)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(solution.names), desc="fit", unit="object", disable=None, dynamic_ncols=True)
    try:
        if client is not None:
            from .cluster import fit_on_dask

            objects = fit_on_dask(client, solution, options, (scene, box, fit_object), bar)
        elif streamed:
            objects = _fit_streamed(solution, options, (scene, box), bar, workers)
        else:
            objects = []
            for obj in solution.objects:
                objects.append(fit_object(obj, options, scene, bar, solution, box))
                if bar is not None:
                    bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    used = any(o.highlight is not None for o in objects)
    return FittedModel(
        objects=tuple(objects),
        emitters=tuple(solution.emitters) if used else (),
        emitter_nodes=solution.emitter_nodes,
        source=str(solution.scene),
        model=("virtual lights (Walter et al. 1997): emitted + Blinn-Phong lights"
               + ("" if options.method == "paper" else f", kinds {options.light_kind}, coefficients {options.coefficients}")),
        settings={
            "lights": options.lights, "target": options.target, "max_lights": options.max_lights,
            "method": options.method, "loss": options.loss, "light_kind": options.light_kind,
            "coefficients": "shared" if options.method == "paper" else options.coefficients,
            "exponent_bounds": list(options.exponent_bounds), "iterations": options.iterations,
            "model": options.glossy_model, "probe_size": options.probe_size,
        },
        camera=solution.camera,
        environment=solution.environment,
    )


def _fit_streamed(source, options, place, bar, workers):
    """The ``FittedObject`` of every object of the ``SolutionFile`` ``source``, in file
    order: glossy ones in worker processes (workers > 1), the costliest (vertices x
    directions) first, while this process copies the diffuse ones; or all here;
    place = (scene geometry, probe box), sent to each worker once."""
    scene, box = place
    names = source.names
    glossy_names = [n for n in names if source.n_directions(n) > 1]
    done = {}

    def tick():
        if bar is not None:
            bar.update(1)

    def here(chosen):
        for name in chosen:
            glossy = name in glossy_names
            obj, alone = _read(source, name, glossy)
            done[name] = fit_object(obj, options, scene, bar, alone, box)
            del obj, alone
            tick()

    cost = costs(source)
    processes = planned_workers(source, workers, cost)
    if processes <= 1:
        threads = planned_threads(source, workers, cost)
        if threads <= 1:
            here(names)
        else:
            _fit_threaded(source, names, (options, place, bar, threads), cost, done)
        return [done[n] for n in names]
    workers = processes
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    order = sorted(glossy_names, key=lambda n: -cost[n])
    threads = max(1, cores() // workers)
    with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                             initializer=_worker_start,
                             initargs=(threads, warnings.showwarning, source.path, scene, box)) as pool:
        futures = {pool.submit(_fit_in_worker, name, options): name for name in order}
        here([n for n in names if n not in cost])  # the diffuse objects, while the workers fit
        for future in as_completed(futures):
            name = futures[future]
            # its textured diffuse term read here, sharing the textures this process holds
            # (a worker's copy of a shared texture is a copy: the staircase's 633 glossy
            # textured objects held 4.4 GB of them)
            done[name] = replace(future.result(), textured=source.textured(name))
            tick()
    return [done[n] for n in names]


def _fit_threaded(source, names, how, cost, done):
    """``_fit_streamed`` in this process: the glossy objects fitted by ``threads``
    threads, the costliest first, while this thread copies the diffuse ones (the numba
    kernels release the GIL; the objects share the imports and the scene). how =
    (options, (scene geometry, probe box), the progress bar or None, threads). The
    file is read by one thread at a time."""
    import threading
    from concurrent.futures import ThreadPoolExecutor, as_completed

    options, (scene, box), bar, threads = how
    lock = threading.Lock()

    def read(name, glossy):
        with lock:
            return _read(source, name, glossy)

    def fitted(name):
        obj, alone = read(name, True)
        return fit_object(obj, options, scene, bar, alone, box)  # the bar shows its lights as they come

    order = sorted(cost, key=lambda n: -cost[n])
    pool = ThreadPoolExecutor(max_workers=threads, thread_name_prefix="fit")
    try:
        futures = {pool.submit(fitted, name): name for name in order}
        for name in names:
            if name not in cost:
                obj, _ = read(name, False)
                done[name] = fit_object(obj, options, scene, bar, None, box)
                if bar is not None:
                    bar.update(1)
        for future in as_completed(futures):
            done[futures[future]] = future.result()
            if bar is not None:
                bar.update(1)
    except BaseException:  # a Ctrl-C (in this thread) or an error: the threads stop at their next evaluation
        mixed.STOP.set()
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
        mixed.STOP.clear()


def planned_threads(source, workers, samples=None):
    """The threads ``fit`` fits the glossy objects of the ``SolutionFile`` ``source``
    with in this process, where it starts no worker processes (``planned_workers``):
    ``workers``, at most one per glossy object (the teapot's scene: the tall block
    fitted while the teapot is)."""
    samples = costs(source) if samples is None else samples
    return max(1, min(workers, len(samples)))


def planned_workers(source, workers, samples=None):
    """The worker processes ``fit`` uses on the ``SolutionFile`` ``source`` when asked
    for ``workers``: at most one per glossy object, and none (1: this process) when one
    object has more than ONE_OBJECT_SHARE of the samples (the teapot: the workers would
    wait for it, having paid their start, about 3 s)."""
    samples = costs(source) if samples is None else samples
    if workers <= 1 or not samples or max(samples.values()) > ONE_OBJECT_SHARE * sum(samples.values()):
        return 1
    return min(workers, len(samples))


_WORKER = {}  # a worker process's solution file, scene geometry and probe box (``_worker_start``)


def _worker_start(threads, show_warning, path, scene, box):
    """A worker process: numba's threads shared out between the workers, warnings shown
    as the parent process shows them (the command's one-line form), and what every
    object's fit reads, received once."""
    import numba

    numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    warnings.showwarning = show_warning
    _WORKER.update(source=SolutionFile(path), scene=scene, box=box)


def _fit_in_worker(name, options):
    """Object ``name`` of the worker's solution file, fitted (in a worker process)."""
    source = _WORKER["source"]
    obj, alone = _read(source, name, True)
    fitted = fit_object(obj, options, _WORKER["scene"], None, alone, _WORKER["box"])
    return replace(fitted, textured=None)  # the parent reads it, shared (``_fit_streamed``)


def _read(source, name, glossy):
    """(object ``name`` of the ``SolutionFile`` ``source``, and for a glossy one the
    ``Solution`` of it alone, whose emitters its fit reads): the object read once, its
    radiance held once (a glossy object's largest array)."""
    if not glossy:
        return source.object(name), None
    alone = source.alone(name)
    return alone.object(name), alone
