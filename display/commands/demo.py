"""``vlights demo``: the whole pipeline on the built-in scenes (``display.demo``), then
optionally the walkthrough window."""

from __future__ import annotations

from fractions import Fraction

from display.gl import check_sample_count
from radiosity.policies import presets

from .common import add_samples_flag, size

__all__ = ["add_command", "run"]


def add_command(subparsers):
    from display.choices import ASPECT
    from display.choices import DEMO_SCENES as SCENES

    scenes = " and ".join(SCENES)
    p = subparsers.add_parser(
        "demo",
        help=f"the whole pipeline on the built-in scenes {scenes}",
        description=f"The whole pipeline on the built-in scenes {scenes}: for each, solution.npz, fit.npz, the "
        "path-traced truth of the scene's camera, the paper's figures 5-7 with FLIP error images and numbers, "
        "and the WebGL walkthrough; then a plot of each glossy object's models (error against floats stored), "
        "report.md and summary.json. Prints, per scene, a table of each display's FLIP on the glossy objects "
        "against the solution and against the truth, the truth's noise floor and a verdict, then where "
        "everything is.",
    )
    p.add_argument("--quality", choices=presets.QUALITIES, default=presets.DEFAULT_QUALITY, help="every knob of every stage at once (default: %(default)s)")
    p.add_argument("--out", default="vlights-demo", metavar="DIR", help="output directory, created if missing (default: %(default)s)")
    wide = "".join(f"; {name}: as wide, {Fraction(h).limit_denominator(64)} of it high" for name, h in ASPECT.items())
    p.add_argument("--size", type=size, default=(512, 512), metavar="WxH", help=f"figure size (default: 512x512{wide})")
    p.add_argument("--view", action="store_true",
                   help=f"open the walkthrough of {SCENES[0]} at the end, where a display exists")
    add_samples_flag(p)
    p.add_argument("--truth-spp", type=int, metavar="N",
                   help="path-trace the first view with N samples per pixel and measure every display against it "
                   "(default: the preset's, " + ", ".join(f"{q} {presets.preset(q).truth_spp}" for q in presets.QUALITIES)
                   + "; 0: no truth)")
    p.set_defaults(func=run)


def run(args):
    from display.demo import FILES, key_numbers, run_demo
    from display.outputs import check_output_dir
    from display.pipeline import check_spp

    check_sample_count(args.samples)
    if args.truth_spp is not None:
        check_spp(args.truth_spp, "--truth-spp", low=0)
    out = check_output_dir(args.out, "--out", files=FILES)
    summary = run_demo(out, args.quality, args.size, samples=args.samples, truth_spp=args.truth_spp)
    print(key_numbers(summary, out))
    if args.view:
        _walkthrough(out, args.samples)
    return 0


def _walkthrough(out, samples):
    """The walkthrough of the first scene's files, where a display exists."""
    from display.window import display_problem

    problem = display_problem()
    if problem is not None:
        print(f"no display ({problem}): skipping the walkthrough (run 'vlights view' where there is one)")
        return
    from display.window import Walkthrough
    from fitting import load_fit
    from radiosity.files.solution import load_solution

    from .view import open_window

    solution = load_solution(out / "cornell-teapot" / "solution.npz")
    Walkthrough.configure(load_fit(out / "cornell-teapot" / "fit.npz"), solution,
                          solution.camera.sized(1280, 720), samples=samples)
    open_window()
