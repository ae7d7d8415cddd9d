"""The radiosity stage's subcommands: ``scene-info`` and ``solve``."""

from __future__ import annotations

import json

from . import options
from .info import describe, format_description
from .loaders import load_scene


def add_quality_flag(parser):
    parser.add_argument(
        "--quality",
        choices=options.QUALITIES,
        default=options.DEFAULT_QUALITY,
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
    p.set_defaults(func=_scene_info)

    p = subparsers.add_parser("solve", help="compute the global-illumination solution (solution.npz)")
    p.set_defaults(func=not_built("solve", "the radiosity solver (issue #3)"))


def _scene_info(args):
    scene = load_scene(args.scene)
    max_edge, how = options.max_edge(scene, args.quality, args.max_edge)
    info = describe(scene, scene.refined(max_edge), max_edge, how)
    print(json.dumps(info, indent=2) if args.json else format_description(info))
    return 0
