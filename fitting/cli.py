"""The fitting stage's subcommand: ``fit``.

A thin layer: the output path is checked first (``check_output``: not the input, a
writable ``.npz``), the flags become ``FitOptions`` (``--quality`` and the solution's
own quality give the defaults of ``--lights`` and ``--iterations``; a flag given
explicitly wins), then ``fit`` runs and ``format_report`` prints the errors.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from radiosity.files.atomic import check_output
from radiosity.files.errors import InputError
from radiosity.files.sniff import SOLUTION, require_format
from radiosity.policies.cluster import check_scheduler, connect
from radiosity.policies.presets import DEFAULT_QUALITY, QUALITIES, preset

from .blocks import BLOCK_SAMPLES
from .memory import check_dask_memory, check_fit_memory, cores
from .options import COEFFICIENTS, LIGHT_KINDS, MODEL_TARGET, MODELS, FitOptions, quality_of


def _lights(text):
    if text == "auto":
        return text
    try:
        return int(text)
    except ValueError:
        raise InputError(f"--lights takes a whole number or 'auto', got {text!r}") from None


def _probe_size(text):
    if text == "auto":
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"takes a whole number or 'auto', got {text!r}") from None


# The most refinement iterations a fit may ask for: one costs up to 1.5 s a glossy object
# at the high preset's grid (see radiosity.policies.presets), so 10,000 are hours per object,
# far past where L-BFGS stops improving (the presets use 25 to 60).
MAX_ITERATIONS = 10_000


def register(subparsers, not_built):
    p = subparsers.add_parser(
        "fit",
        help="fit each glossy object's model (emitters' highlights, reflection probe, virtual lights) to a "
        "solution (fit.npz)",
        description="Fit each glossy object's model: the emitters' own highlights in closed form, a "
        "reflection probe for its surroundings and virtual lights for what remains (each object gets the "
        "cheapest that reaches the error target: --model auto), or virtual lights alone as the paper does "
        "(Walter et al. 1997; --model lights): each light directional or positional as the data require, "
        "with a specular coefficient per light at each vertex, refined by variable projection; --method "
        "paper runs the paper's section 3.2 exactly. Writes fit.npz (its format: docs/formats.md) and "
        "prints each object's model and error.",
    )
    def per_quality(show):
        return "; ".join(f"{q} {show(preset(q))}" for q in QUALITIES)

    p.add_argument("solution", help="a solution.npz from 'vlights solve'")
    p.add_argument("-o", "--output", default="fit.npz", help="output file (default: %(default)s)")
    p.add_argument("--quality", choices=QUALITIES, default=None,
                   help="sets the defaults of --lights, --iterations and the probe sizes --probe-size auto tries ("
                   + per_quality(lambda k: f"{k.probe_lights} lights beside a probe, {k.fit_lights} alone, "
                                 f"{k.fit_iterations} iterations, probes {', '.join(map(str, k.probe_sizes))}")
                   + f"); a flag given explicitly wins (default: the quality the solution was solved at, else "
                   f"{DEFAULT_QUALITY})")
    p.add_argument("--lights", default=None, metavar="K",
                   help="virtual lights per glossy object, 0 to 64, or 'auto': as many as --target needs, at most "
                   "--max-lights (default: the quality's, beside a probe or alone: see --quality)")
    p.add_argument("--model", choices=MODELS, default="auto",
                   help="what a glossy object's model is made of: auto (the cheapest reaching --model-target), "
                   "diffuse (one colour per vertex), emitters (and the emitters' highlights in closed form), probe "
                   "(and a reflection probe), probe+lights (and virtual lights), lights (virtual lights alone on the "
                   "whole radiance, as the paper; --method paper always is) (default: %(default)s)")
    p.add_argument("--probe-size", type=_probe_size, default="auto", metavar="M",
                   help="the reflection probe's M x M texels, or auto: the quality's sizes (see --quality) tried, "
                   "the cheapest within reach of the best kept (default: %(default)s)")
    p.add_argument("--target", type=float, default=0.1, metavar="E",
                   help="relative RMS error target of --lights auto (default: %(default)s)")
    p.add_argument("--model-target", type=float, default=MODEL_TARGET, metavar="E",
                   help="error target of --model auto: relative RMS in a space near what a viewer sees (radiance to "
                   "the display's gamma, scaled by the object's mean) (default: %(default)s)")
    p.add_argument("--max-lights", type=int, default=16, metavar="N", help="most lights --lights auto may use, 1 to 64 (default: %(default)s)")
    p.add_argument("--method", choices=("paper", "refined", "per-light"), default="refined",
                   help="paper: section 3.2 exactly; refined: then non-linear refinement; per-light: refined with an exponent per light (default: %(default)s)")
    p.add_argument("--light-kind", choices=LIGHT_KINDS, default="auto",
                   help="auto: each light directional or positional, whichever the error asks for; or all of one kind "
                   "(refined methods; default: %(default)s)")
    p.add_argument("--coefficients", choices=COEFFICIENTS, default="per-light",
                   help="per-light: a specular coefficient per light at each vertex (3 + 3K numbers a vertex); shared: one "
                   "for all lights, the paper's model (6 numbers a vertex) (refined methods; default: %(default)s)")
    p.add_argument("--loss", choices=("auto", "linear", "relative"), default="auto",
                   help="error measure to minimise: linear least squares, or relative to the radiance; auto: --model "
                   "auto fits both and keeps the one the perceptual error prefers (relative keeps dim reflections, "
                   "linear does not fit a noisy solution's near-zero samples), another --model relative for the "
                   "models with a probe, linear for lights alone (default: %(default)s)")
    p.add_argument("--exponent-bounds", type=float, nargs=2, default=(1.0, 1e4), metavar=("LOW", "HIGH"),
                   help="range of the exponent search (default: 1 10000)")
    p.add_argument("--iterations", type=int, default=None, metavar="N",
                   help=f"refinement iterations, 0 to {MAX_ITERATIONS:,} (default: the quality's: see --quality)")
    p.add_argument("--search-samples", type=int, default=None, metavar="N",
                   help="a glossy object's model (the comparison of --model auto, the probe's texels, the lights) is "
                   "searched for on every k-th vertex, at most N samples (vertex x direction), its per-vertex "
                   "coefficients then solved on every vertex; more is slower and holds more memory, about 1.2 kB a "
                   "sample (default: the quality's: " + per_quality(lambda k: f"{k.fit_search_samples:,}") + ")")
    p.add_argument("--block-samples", type=int, default=BLOCK_SAMPLES, metavar="N",
                   help="samples of a block of vertices in the per-vertex pass: memory only, the same model "
                   "whatever N (default: %(default)s)")
    p.add_argument("--workers", type=_workers, default=None, metavar="N",
                   help="processes fitting glossy objects at once, the costliest first (threads of this one where "
                   "one object is most of the work); the model is the same whatever N (default: one per core)")
    p.add_argument("--scheduler", default="threads", metavar="WHERE",
                   help="where the glossy objects are fitted: threads (this machine, --workers processes; default), "
                   "dask (a Dask LocalCluster sized to this machine) or tcp://HOST:PORT (a running Dask scheduler); "
                   "the same model, bit for bit, on any (needs pip install \".[dask]\")")
    p.set_defaults(func=_fit)


def _workers(text):
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"takes a whole number, got {text!r}") from None
    if not 1 <= n <= 256:
        raise argparse.ArgumentTypeError(f"takes a whole number from 1 to 256, got {n}")
    return n


def fit_quality(args_quality, solution):
    """(quality, how it was chosen): ``--quality`` if given, else the quality recorded
    in the solution's ``settings["quality"]`` if it is one we know, else the default
    (``fitting.options.quality_of``)."""
    if args_quality is not None:
        return args_quality, "--quality"
    return quality_of(solution)


def fit_options(args, quality):
    """The ``FitOptions`` of the command line: explicit flags win over ``quality``'s preset."""
    knobs = preset(quality)
    lights = _lights(args.lights) if args.lights is not None else knobs.fit_lights
    probe_lights = _lights(args.lights) if args.lights is not None else knobs.probe_lights
    iterations = args.iterations if args.iterations is not None else knobs.fit_iterations
    if iterations > MAX_ITERATIONS:
        raise InputError(f"--iterations must be a whole number from 0 to {MAX_ITERATIONS:,}, got {iterations}")
    return FitOptions(
        lights=lights, target=args.target, max_lights=args.max_lights, method=args.method,
        light_kind=args.light_kind, coefficients=args.coefficients, loss=args.loss, exponent_bounds=tuple(args.exponent_bounds), iterations=iterations,
        model=args.model, probe_size=args.probe_size, probe_sizes=tuple(knobs.probe_sizes), probe_lights=probe_lights,
        model_target=args.model_target,
        search_samples=args.search_samples if args.search_samples is not None else knobs.fit_search_samples,
        block_samples=args.block_samples,
    ).check()


# What the flags that shape virtual lights, the probe or a fit's loss are, with their
# defaults: given with a model that has no such part, a flag would be dropped without a word
LIGHT_FLAGS = (("--lights", "lights", None), ("--method", "method", "refined"), ("--light-kind", "light_kind", "auto"),
               ("--coefficients", "coefficients", "per-light"), ("--target", "target", 0.1),
               ("--max-lights", "max_lights", 16), ("--iterations", "iterations", None),
               ("--exponent-bounds", "exponent_bounds", (1.0, 1e4)))
NO_LIGHTS = ("diffuse", "emitters", "probe")
NO_PROBE = ("diffuse", "emitters", "lights")


def _given(args, names):
    """The flags among ``names`` ((flag, attribute, default)) given a value other than their default."""
    def value(attr):
        v = getattr(args, attr)
        return tuple(v) if isinstance(v, list) else v  # nargs flags come as lists
    return [flag for flag, attr, default in names if value(attr) is not None and value(attr) != default]


def check_combination(args):
    """Refuse in one line (InputError) a flag that the chosen --model or --method cannot
    honour: no flag the user gives is dropped without a word."""
    model, method = args.model, args.method
    if method == "paper":
        if model not in ("auto", "lights"):
            raise InputError(f"--method paper fits virtual lights alone (the paper's model): it does not go with "
                             f"--model {model}")
        if args.light_kind == "positional":
            raise InputError("--method paper has directional lights (section 3.2): --light-kind positional is for the "
                             "refined methods")
    if model in NO_LIGHTS:
        given = _given(args, LIGHT_FLAGS)
        if given:
            raise InputError(f"{given[0]} shapes virtual lights: --model {model} has none (use --model probe+lights, "
                             f"lights or auto)")
    if model in NO_PROBE and args.probe_size != "auto":
        raise InputError(f"--probe-size shapes the reflection probe: --model {model} has none (use --model probe, "
                         f"probe+lights or auto)")
    if model == "diffuse" and args.loss != "auto":
        raise InputError("--model diffuse fits nothing (each vertex's mean over its directions): --loss does not go "
                         "with it")
    if model == "probe+lights" and args.lights is not None and _lights(args.lights) == 0:
        raise InputError("--lights 0 leaves --model probe+lights no lights (use --model probe)")
    lights = None if args.lights is None else _lights(args.lights)
    if lights != "auto":
        given = _given(args, LIGHT_FLAGS[4:6])
        if given:
            count = "the quality's number of" if lights is None else f"--lights {lights}"
            raise InputError(f"{given[0]} is for --lights auto (how many lights it adds): it does nothing with "
                             f"{count} lights")


def _fit(args):
    out = check_output(args.output, ".npz", inputs=(args.solution,), flag="-o")
    fit_options(args, args.quality or DEFAULT_QUALITY)  # bad flags are refused before the solution is read
    check_combination(args)
    if args.scheduler != "threads":
        check_scheduler(args.scheduler)
        if args.workers is not None:
            raise InputError("--workers sets this machine's processes: it does not go with --scheduler "
                             f"{args.scheduler} (the cluster's workers fit the objects)")
    from radiosity.files.solution import SolutionFile  # numba's: loaded once the flags are checked

    from .fit import fit, planned_threads, planned_workers

    require_format(args.solution, (SOLUTION,), "solution")
    with SolutionFile(args.solution) as solution:
        solution.validate()  # a bad object is one line before the estimate, not after it and some work
        quality, chosen_by = fit_quality(args.quality, solution)
        options = fit_options(args, quality)
        if args.scheduler == "threads":
            asked = args.workers or cores()
            processes = planned_workers(solution, asked)
            threads = planned_threads(solution, asked) if processes <= 1 else 0
            workers = check_fit_memory(solution, processes if processes > 1 else threads, threads=processes <= 1,
                                       search_samples=options.search_samples, block_samples=options.block_samples)
            model = fit(solution, options, progress=True, workers=workers)
        else:
            model = _fit_on(args.scheduler, solution, options)
    model = replace(model, settings={**model.settings, "quality": quality, "quality_chosen_by": chosen_by})
    model.save(out)
    print(format_report(model, out))
    return 0


def _fit_on(scheduler, solution, options):
    """``fit`` on the Dask cluster ``scheduler`` names (``radiosity.policies.cluster.connect``):
    its own memory estimate is of the objects in flight, said like the local one's."""
    client, cluster = connect(scheduler)
    try:
        threads = sum(client.nthreads().values())
        check_dask_memory(solution, 2 * threads + 1, search_samples=options.search_samples,
                          block_samples=options.block_samples)
        # one write: a Ctrl-C cannot come between the line and its end
        sys.stderr.write(f"fit: on dask {client.scheduler.address} ({threads} threads)\n")
        from .fit import fit

        return fit(solution, options, progress=True, client=client)
    finally:
        try:
            client.close()
        finally:
            if cluster is not None:
                cluster.close()


def _number(value, width, digits=4):
    return f"{'-':>{width}}" if value is None else f"{value:>{width}.{digits}f}"


def format_report(model, path):
    """Per glossy object: its model (what "auto" chose and from what), lights, exponents,
    stored floats, error of the fit (relative RMS, and in the viewer's space) and of the
    best colour per vertex alone; diffuse objects in one row each, without numbers."""
    lines = [
        f"{'object':<14} {'model':<13} {'K':>3} {'kinds':<7} {'probe':>6} {'floats/v':>8} {'exponent(s)':<14} "
        f"{'rel. RMS':>9} {'perceptual':>10} {'diffuse only':>13} {'time':>7}"
    ]
    for o in model.objects:
        if o.info.get("method") == "diffuse":
            lines.append(f"{o.name:<14} {'diffuse':<13} {'-':>3} (a diffuse material: one colour per vertex)")
            continue
        if o.glass is not None:
            lines.append(f"{o.name:<14} {'glass':<13} {'-':>3} ({o.glass.kind} eta {o.glass.eta:.3g}: drawn as glass, "
                         "reflecting and refracting its surroundings)")
            continue
        if o.mirror is not None:
            lines.append(f"{o.name:<14} {'mirror':<13} {'-':>3} (a perfect mirror: drawn by what it reflects)")
            continue
        e = o.info["error"]
        exps = o.info["shininess"]
        shown = "-" if not exps else (f"{exps[0]:.4g}" if len(set(exps)) == 1 else f"{min(exps):.3g} .. {max(exps):.3g}")
        n_point = int(np.count_nonzero(o.positional))
        kinds = f"{n_point}P {o.n_lights - n_point}D" if o.n_lights else "-"
        probe = f"{o.probe.size}^2" if o.probe is not None else "-"
        lines.append(
            f"{o.name:<14} {o.info.get('model', 'lights'):<13} {o.n_lights:>3} {kinds:<7} {probe:>6} "
            f"{o.floats_per_vertex:>8} {shown:<14} {_number(e['relative_rms'], 9)} {_number(e.get('perceptual'), 10)} "
            f"{_number(e['diffuse_only_relative_rms'], 13)} {o.info['time_s']:>6.2f}s"
        )
        tried = o.info.get("tried") or []
        if len(tried) > 1:
            alternatives = ", ".join(
                f"{t['model']}{' ' + str(t['probe_size']) if t['probe_size'] else ''}"
                f"{' ' + str(t['lights']) + 'L' if t['lights'] else ''}{' ' + t['loss'][:3] if t.get('loss') else ''}"
                f"{'*' if t.get('above_floor') else ''} {t['perceptual']:.3g} ({t['floats'] / 1000:.0f}k)"
                for t in tried
            )
            lines.append(f"{'':<14} tried (perceptual error, floats; rel/lin: the loss; *: worse than the diffuse "
                         f"walkthrough): {alternatives}")
        if "not reached" in o.info.get("chosen_by", ""):
            lines.append(f"{'':<14} {o.info['chosen_by']}")
        if "diffuse walkthrough" in o.info.get("why_kept", ""):  # the floor decided
            lines.append(f"{'':<14} {o.info['why_kept']}")
    floored = [o for o in model.objects if o.info.get("why_kept", "").startswith("kept diffuse")]
    if floored:
        lines.append(f"kept diffuse: every other model was worse than the diffuse walkthrough on {len(floored)} of "
                     f"{sum(1 for o in model.objects if 'tried' in o.info)} glossy objects "
                     f"({', '.join(o.name for o in floored[:6])}{', ...' if len(floored) > 6 else ''})")
    size = Path(path).stat().st_size
    settings = model.settings
    how = f"model {settings.get('model', 'lights')}, method {settings['method']}, loss {settings['loss']}"
    if settings["method"] != "paper":
        how += f", light kinds {settings.get('light_kind')}, coefficients {settings.get('coefficients')}"
    if "quality" in settings:
        how += f", quality {settings['quality']} (lights {settings['lights']}, iterations {settings['iterations']})"
    lines.append(f"wrote {path} ({size / 1e6:.2f} MB); {how}")
    return "\n".join(lines)
