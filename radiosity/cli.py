"""The radiosity stage's subcommands: ``scene-info`` and ``solve``."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from radiosity.formats import presets
from radiosity.formats.atomic import check_output
from radiosity.info import describe, format_description
from radiosity.scene.loaders import load_scene


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


def add_quality_flag(parser):
    parser.add_argument(
        "--quality",
        choices=presets.QUALITIES,
        default=presets.DEFAULT_QUALITY,
        help="set every speed/accuracy knob at once (default: %(default)s)",
    )


def register(subparsers, not_built):
    p = subparsers.add_parser(
        "scene-info",
        help="print how a scene was understood: objects, triangles, materials, emitters, bounds",
        description="Load a scene and print how it was understood: objects, triangles and "
        "vertices before and after mesh refinement, materials, emitters and their power, bounds.",
    )
    p.add_argument("scene", help="a .toml scene, a mesh file (.obj, .gltf, .glb, ...) or a built-in: cornell, cornell-teapot")
    add_quality_flag(p)
    p.add_argument("--max-edge", type=float, metavar="L", help="refine to edges no longer than L (scene units); overrides --quality")
    p.add_argument("--json", action="store_true", help="print the description as JSON")
    add_adaptive_flags(p)
    p.set_defaults(func=_scene_info)

    p = subparsers.add_parser(
        "solve",
        help="compute the view-independent global-illumination solution (solution.npz)",
        description="Photon tracing on Embree, local linear density estimation and a directional "
        "gather at every vertex of each glossy object; writes solution.npz (its format: docs/formats.md). "
        "--quality sets every knob; each knob's own flag overrides it.",
    )
    p.add_argument("scene", help="a .toml scene, a mesh file or a built-in: cornell, cornell-teapot")
    p.add_argument("-o", "--output", default="solution.npz", help="output file (default: %(default)s)")
    add_quality_flag(p)
    p.add_argument("--photons", type=int, metavar="N", help="photons emitted in total")
    p.add_argument("--gather-samples", type=int, metavar="N", help="gather rays per glossy vertex (rounded up to a square)")
    p.add_argument("--light-samples", type=int, metavar="N", help="light samples per glossy vertex")
    p.add_argument("--grid", type=int, metavar="N", help="n x n direction grid for every glossy object (default: from each exponent)")
    p.add_argument("--max-edge", type=float, metavar="L", help="refine to edges no longer than L (scene units): a uniform mesh, unless --adaptive")
    p.add_argument(
        "--kernel-rings",
        type=whole_number(0, presets.MAX_KERNEL_RINGS),
        metavar="K",
        help=f"widen each vertex's density kernel by K rings of neighbours, 0 to {presets.MAX_KERNEL_RINGS} "
        "(less noise, more blur)",
    )
    p.add_argument(
        "--extra-gather",
        type=float,
        metavar="F",
        help="further gather passes where the gather is noisy, at most F times the glossy vertices (0: none)",
    )
    p.add_argument(
        "--gather-tolerance",
        type=float,
        metavar="E",
        help="the relative standard error the extra gather passes aim at",
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
        help="shadow rays per glossy vertex and emitter part: how much of each emitter a vertex sees",
    )
    p.add_argument(
        "--emitter-nodes",
        type=int,
        metavar="N",
        help="quadrature nodes of the emitters' highlights (1-32; more: more exact, slower to draw)",
    )
    add_adaptive_flags(p)
    p.add_argument("--seed", type=int, default=1, help="random seed (default: %(default)s)")
    p.add_argument("--threads", type=int, metavar="T", help="worker threads (default: one per core)")
    p.add_argument(
        "--scheduler",
        default="threads",
        metavar="WHERE",
        help="where the photon batches and gather blocks run: threads (this process, default), dask (a Dask "
        "LocalCluster sized to this machine) or tcp://HOST:PORT (a running Dask scheduler); same seed, same "
        "solution on any (needs pip install \".[dask]\")",
    )
    p.set_defaults(func=_solve)


def add_adaptive_flags(parser):
    parser.add_argument(
        "--adaptive",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="refine the mesh where the light changes: a first pass, then the edges whose light linear "
        "interpolation does not explain are split, and the solve runs again (default: the --quality preset; "
        "off when --max-edge asks for a uniform mesh)",
    )
    parser.add_argument(
        "--vertex-budget",
        type=int,
        metavar="N",
        help="most vertices of the adaptively refined scene (default: the preset's vertex_budget_factor "
        "times the uniform mesh's)",
    )


def adaptive_options(args):
    from radiosity.transport.adaptive import AdaptiveOptions

    return AdaptiveOptions(enabled=args.adaptive, vertex_budget=args.vertex_budget)


def _output_path(path, suffix=".npz", inputs=()):
    """Check an output path before hours of work go into it (``check_output``)."""
    return check_output(path, suffix, inputs=inputs, flag="output")


def _solve(args):
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
    adaptive.resolved(args.quality, scene.refined(settings["max_edge"]).n_vertices, args.max_edge is not None)
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
        what = "sphere" if p.kind == "sphere" else f"{len(p.points)}-gon"
        kinds.setdefault(p.source, []).append(what)
    described = ", ".join(f"{name} ({', '.join(k)})" for name, k in kinds.items())
    if len(kinds) > LISTED:
        shapes = {}
        for k in kinds.values():
            for what in k:
                shapes[what] = shapes.get(what, 0) + 1
        described = f"from {len(kinds):,} objects ({', '.join(f'{what} x {n}' for what, n in shapes.items())})"
    st = solution.stats
    return [
        f"  highlights {len(parts)} emitter part(s) in closed form: {described}; "
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
    scene = load_scene(args.scene)
    max_edge, how = presets.max_edge(scene, args.quality, args.max_edge)
    refined = scene.refined(max_edge)
    adaptive = adaptive_options(args).resolved(args.quality, refined.n_vertices, args.max_edge is not None)
    info = describe(scene, refined, max_edge, how, adaptive)
    print(json.dumps(info, indent=2) if args.json else format_description(info))
    return 0
