"""The radiosity stage's subcommands: ``scene-info`` and ``solve``."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from radiosity.files.atomic import check_output
from radiosity.files.sniff import scene_words
from radiosity.policies import presets
from radiosity.policies.limits import MAX_NODES


def whole_number(low, high=None):
    """An argparse type: a whole number in [low, high] (high None: no upper bound),
    refused at parse time in one line otherwise."""

    def parse(text):
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"takes a whole number, got {text!r}") from None
        if value < low or (high is not None and value > high):
            shown = f"from {low} to {high}" if high is not None else f">= {low}"
            raise argparse.ArgumentTypeError(f"takes a whole number {shown}, got {value}")
        return value

    return parse


def preset_values(knob, show="{}".format):
    """A knob's value at each quality, from the presets' one table, for help texts (which
    then stay true when the table changes): "draft 1, medium 2, high 3", or "1 at every
    quality"."""
    values = [show(getattr(presets.preset(q), knob)) for q in presets.QUALITIES]
    if len(set(values)) == 1:
        return f"{values[0]} at every quality"
    return ", ".join(f"{q} {v}" for q, v in zip(presets.QUALITIES, values))


def add_quality_flag(parser, what="set every speed/accuracy knob at once"):
    parser.add_argument(
        "--quality",
        choices=presets.QUALITIES,
        default=presets.DEFAULT_QUALITY,
        help=f"{what} (default: %(default)s)",
    )


def register(subparsers, not_built):
    p = subparsers.add_parser(
        "scene-info",
        help="print how a scene was understood: objects, triangles, materials, emitters, bounds",
        description="Load a scene and print how it was understood: its camera and bounds, materials (kind, "
        "kd, ks, Phong exponent, albedo, emission), objects with their triangles and vertices before and after "
        "mesh refinement, and emitters (lamps, and point, spot and directional lights) with their power. Whatever "
        "was approximated or left out on the way in "
        "(a material mapped onto the Phong lobe, glass left out, a texture taken as its mean colour, degenerate "
        "triangles dropped) is said in a warning on stderr: read them first when a solution looks wrong. "
        "Quick: nothing is solved.",
    )
    p.add_argument("scene", help=scene_words())
    add_quality_flag(p, "the preset whose mesh refinement is shown: edges no longer than the scene's diagonal / "
                     + preset_values("max_edge_divisor"))
    p.add_argument("--max-edge", type=float, metavar="L", help="refine to edges no longer than L (scene units); overrides --quality")
    p.add_argument("--json", action="store_true", help="print the description as JSON")
    add_adaptive_flags(p, shown=True)
    p.set_defaults(func=_scene_info)

    p = subparsers.add_parser(
        "solve",
        help="compute the view-independent global-illumination solution (solution.npz)",
        description="Photon tracing on Embree, local linear density estimation and a directional gather at every "
        "vertex of each glossy object, on a mesh refined where the light changes; writes solution.npz (its "
        "format: docs/formats.md) and prints the work done, the time of each phase and the file's size. "
        "--quality sets every knob; each knob's own flag overrides it.",
    )
    p.add_argument("scene", help=scene_words())
    p.add_argument("-o", "--output", default="solution.npz", help="output file (default: %(default)s)")
    add_quality_flag(p)
    p.add_argument("--photons", type=int, metavar="N",
                   help=f"photons emitted in total (default: {preset_values('photons', '{:,}'.format)})")
    p.add_argument("--gather-samples", type=int, metavar="N",
                   help="gather rays per glossy vertex, rounded up to a square (default: "
                   f"{preset_values('gather_samples')})")
    p.add_argument("--light-samples", type=int, metavar="N",
                   help=f"the gather's samples of the emitters per glossy vertex (default: {preset_values('light_samples')})")
    p.add_argument("--grid", type=int, metavar="N",
                   help="n x n direction grid, 1 to 256, for every glossy object (default: each object's own, 8 to "
                   "64, from its Phong exponent and the quality)")
    p.add_argument("--max-edge", type=float, metavar="L",
                   help="refine to edges no longer than L (scene units): a uniform mesh, unless --adaptive (default: "
                   f"the scene's diagonal / {preset_values('max_edge_divisor')})")
    p.add_argument(
        "--kernel-rings",
        type=whole_number(0, presets.MAX_KERNEL_RINGS),
        metavar="K",
        help=f"widen each vertex's density kernel by K rings of neighbours, 0 to {presets.MAX_KERNEL_RINGS} "
        f"(less noise, more blur; default: {preset_values('kernel_rings')})",
    )
    p.add_argument(
        "--min-photons",
        type=whole_number(0, presets.MAX_MIN_PHOTONS),
        metavar="N",
        help=f"widen a density kernel whose support holds fewer than N photons, ring by ring, up to "
        f"{presets.MAX_SPARSE_RINGS} rings more within --max-edge (0: never; more: less noise, more blur; "
        f"default: {presets.MIN_PHOTONS})",
    )
    p.add_argument(
        "--extra-gather",
        type=float,
        metavar="F",
        help="further gather passes where the gather is noisy, at most F times the glossy vertices (0: none; "
        f"default: {preset_values('extra_gather')})",
    )
    p.add_argument(
        "--gather-tolerance",
        type=float,
        metavar="E",
        help=f"the relative standard error the extra gather passes aim at (default: {preset_values('gather_tolerance')})",
    )
    p.add_argument(
        "--emitter-highlights",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="the emitters' own glossy highlights in closed form, which every display then draws per pixel "
        "(default); --no-emitter-highlights gathers them into the direction grid like any other light",
    )
    p.add_argument(
        "--visibility-samples",
        type=int,
        metavar="N",
        help="shadow rays per glossy vertex and emitter part: how much of each emitter a vertex sees (default: "
        f"{preset_values('visibility_samples')})",
    )
    p.add_argument(
        "--emitter-nodes",
        type=int,
        metavar="N",
        help=f"quadrature nodes of the emitters' highlights, 1 to {MAX_NODES}: more is more exact and slower to "
        f"draw (default: {preset_values('emitter_nodes')})",
    )
    add_adaptive_flags(p)
    p.add_argument("--seed", type=int, default=1, help="random seed: same seed, same solution (default: %(default)s)")
    p.add_argument("--threads", type=int, metavar="T",
                   help="worker threads (default: one per core); the solution does not depend on them")
    p.add_argument(
        "--scheduler",
        default="threads",
        metavar="WHERE",
        help="where the photon batches and gather blocks run: threads (this process, default), dask (a Dask "
        "LocalCluster sized to this machine) or tcp://HOST:PORT (a running Dask scheduler); same seed, same "
        "solution on any (needs pip install \".[dask]\")",
    )
    p.set_defaults(func=_solve)


def add_adaptive_flags(parser, shown=False):
    """--adaptive and --vertex-budget; ``shown``: scene-info's, which reports the
    refinement a solve would do without doing it."""
    what = ("report the refinement a solve would do where the light changes (on or off, its vertex budget); "
            "only the solve refines" if shown else
            "refine the mesh where the light changes: a first pass, then the edges whose light linear "
            "interpolation does not explain are split, and the solve runs again")
    on = [q for q in presets.QUALITIES if presets.preset(q).adaptive]
    default = "every preset" if len(on) == len(presets.QUALITIES) else ", ".join(on) or "no preset"
    parser.add_argument(
        "--adaptive",
        action=argparse.BooleanOptionalAction,
        default=None,
        help=f"{what} (default: on at {default}; off when --max-edge asks for a uniform mesh)",
    )
    parser.add_argument(
        "--vertex-budget",
        type=int,
        metavar="N",
        help="most vertices of the adaptively refined scene (default: "
        f"the uniform mesh's times {preset_values('vertex_budget_factor', '{:g}'.format)})",
    )


def adaptive_options(args):
    from radiosity.transport.adaptive import AdaptiveOptions

    return AdaptiveOptions(enabled=args.adaptive, vertex_budget=args.vertex_budget)


def _output_path(path, suffix=".npz", inputs=()):
    """Check an output path before hours of work go into it (``check_output``)."""
    return check_output(path, suffix, inputs=inputs, flag="output")


def _solve(args):
    from radiosity.scene.loaders import load_scene  # the scene stack and numba: once the command runs
    from radiosity.transport.adaptive import solve_adaptive
    from radiosity.transport.solve import SolveOptions

    out = _output_path(args.output, inputs=(args.scene,) if Path(args.scene).exists() else ())
    scene = load_scene(args.scene)
    opts = SolveOptions(
        quality=args.quality,
        photons=args.photons,
        gather_samples=args.gather_samples,
        light_samples=args.light_samples,
        grid=args.grid,
        max_edge=args.max_edge,
        kernel_rings=args.kernel_rings,
        min_photons=args.min_photons,
        extra_gather=args.extra_gather,
        gather_tolerance=args.gather_tolerance,
        emitter_highlights=args.emitter_highlights,
        visibility_samples=args.visibility_samples,
        emitter_nodes=args.emitter_nodes,
        seed=args.seed,
        threads=args.threads,
        scheduler=args.scheduler,
    )
    settings = opts.resolved(scene)  # refuse bad knobs before any work
    adaptive = adaptive_options(args)
    adaptive.resolved(args.quality, scene.refined(settings.max_edge).n_vertices, args.max_edge is not None)
    solution = solve_adaptive(scene, opts, adaptive, progress=True)
    solution.save(out)
    print(format_summary(solution, out))
    return 0


LISTED = 8  # the summary names up to this many objects on a line; past it, it counts them


def format_summary(solution, path):
    """The end-of-solve summary: work done, speed, time per phase, output size."""
    st = solution.stats
    t = st["time_s"]
    total = sum(t.values())
    glossy = {o.name: f"{o.grid_n}x{o.grid_n}" for o in solution.objects if not o.is_diffuse}
    if len(glossy) > LISTED:  # a large scene: how many objects have each grid, not every name
        counts = {}
        for grid in glossy.values():
            counts[grid] = counts.get(grid, 0) + 1
        grids = ", ".join(f"{grid} x {n}" for grid, n in sorted(counts.items(), key=lambda g: int(g[0].split("x")[0])))
        grids = f"{len(glossy):,} glossy objects: {grids}"
    else:
        grids = ", ".join(f"{k} {v}" for k, v in glossy.items())
    size = Path(path).stat().st_size
    where = st.get("scheduler", "threads")
    lines = [
        f"solved {solution.scene}: {st['triangles']} triangles, {st['vertices']} vertices, "
        f"quality {st['quality']}, seed {st['seed']}, {st['threads']} threads"
        + ("" if where == "threads" else f" on {where}"),
        f"  photons  {st['photons']:,} traced, {st['photon_rays']:,} rays, "
        f"{st['photon_rays_per_s'] / 1e6:.2f} M rays/s, {t['photons']:.2f} s",
        f"  density  {t['density']:.2f} s",
        (
            f"  gather   {st['gather_rays']:,} rays, {st['gather_rays_per_s'] / 1e6:.2f} M rays/s, "
            f"{t['gather']:.2f} s  (grids: {grids})"
            if glossy
            else "  gather   none: no glossy objects"
        ),
        *_regather_lines(st.get("regather")),
        *_highlight_lines(solution),
        f"  total    {total:.2f} s (setup {t['setup']:.2f} s)",
        *_adaptive_lines(st.get("adaptive")),
        f"wrote {path} ({size / 1e6:.2f} MB)",
    ]
    return "\n".join(lines)


def _regather_lines(regather):
    """The summary's line on the extra gather passes (none where none ran)."""
    ran = {name: r for name, r in (regather or {}).items() if r["extra_passes"]}
    if not ran:
        return []
    if len(ran) > LISTED:
        rs = ran.values()
        tolerances = [r["tolerance"] for r in rs]
        return [
            f"  regather {len(ran):,} objects, {sum(r['regathered'] for r in rs):,} vertices "
            f"+{sum(r['extra_passes'] for r in rs):,} passes (at most {max(r['max_passes'] for r in rs)}, "
            f"tolerance {min(tolerances):.3g} to {max(tolerances):.3g})"
        ]
    parts = [
        f"{name} {r['regathered']:,} vertices +{r['extra_passes']:,} passes (at most {r['max_passes']}, "
        f"tolerance {r['tolerance']:.3g})"
        for name, r in ran.items()
    ]
    return ["  regather " + "; ".join(parts)]


def _highlight_lines(solution):
    """The summary's line on the emitters' closed-form highlights."""
    parts = solution.emitters
    if not parts:
        return []
    kinds = {}
    for p in parts:
        if p.kind == "point":
            what = "spot" if p.spot is not None else "point"
        else:
            what = {"sphere": "sphere", "polygon": f"{len(p.points)}-gon", "direction": "directional"}[p.kind]
        kinds.setdefault(p.source, []).append(what)
    described = ", ".join(f"{name} ({', '.join(k)})" for name, k in kinds.items())
    if len(kinds) > LISTED:
        shapes = {}
        for k in kinds.values():
            for what in k:
                shapes[what] = shapes.get(what, 0) + 1
        described = f"from {len(kinds):,} objects ({', '.join(f'{what} x {n}' for what, n in shapes.items())})"
    from radiosity.transport.highlights import LEFT_OUT

    st = solution.stats
    own = [len(o.emitter_parts) for o in solution.objects if o.emitter_parts is not None]
    drawn = (f"; each glossy object draws the brightest for it per pixel ({min(own)} to {max(own)}), its grid "
             f"holds those that reach it (less the dimmest, under {LEFT_OUT:.0%} of its light)" if own else "")
    return [
        f"  highlights {len(parts)} emitter part(s) in closed form: {described}{drawn}; "
        f"{st.get('visibility_rays', 0):,} shadow rays, {st['time_s'].get('highlights', 0.0):.2f} s"
    ]


def _adaptive_lines(adaptive):
    """The summary's lines on the refinement (none for a solve without its stats)."""
    if not adaptive:
        return []
    if not adaptive["enabled"]:
        return [f"  mesh     uniform, {adaptive['vertices_before']:,} vertices (--no-adaptive)"]
    passes = adaptive["passes"]
    seconds = sum(p["time_s"] for p in passes)
    return [
        f"  mesh     refined where the light changes: {adaptive['vertices_before']:,} -> "
        f"{adaptive['vertices_after']:,} vertices (budget {adaptive['vertex_budget']:,}), "
        f"{len(passes)} estimate pass(es) {seconds:.2f} s before the final solve"
    ]


def _scene_info(args):
    from radiosity.info import describe, format_description
    from radiosity.scene.loaders import load_scene

    scene = load_scene(args.scene)
    max_edge, how = presets.max_edge(scene, args.quality, args.max_edge)
    refined = scene.refined(max_edge)
    adaptive = adaptive_options(args).resolved(args.quality, refined.n_vertices, args.max_edge is not None)
    info = describe(scene, refined, max_edge, how, adaptive)
    print(json.dumps(info, indent=2) if args.json else format_description(info))
    return 0
