"""``vlights demo``: the whole pipeline on the built-in scenes (``display.demo``), then
optionally the walkthrough window."""

from __future__ import annotations

from display.gl import check_sample_count
from radiosity.formats import presets

from .common import add_samples_flag, size

__all__ = ["add_command", "run"]


def add_command(subparsers):
    p = subparsers.add_parser(
        "demo",
        help="solve, fit and compare the built-in scenes cornell-teapot and plates",
        description="The whole pipeline on the built-in scenes cornell-teapot and plates: for each, solution.npz, "
        "fit.npz, the paper's figures 5-7 with error images and numbers against a path-traced truth, and the "
        "WebGL walkthrough; then a plot of each glossy object's models (error against floats stored), "
        "report.md and summary.json.",
    )
    p.add_argument("--quality", choices=presets.QUALITIES, default=presets.DEFAULT_QUALITY, help="every knob of every stage at once (default: %(default)s)")
    p.add_argument("--out", default="vlights-demo", metavar="DIR", help="output directory, created if missing (default: %(default)s)")
    p.add_argument("--size", type=size, default=(512, 512), metavar="WxH", help="figure size (default: 512x512)")
    p.add_argument("--view", action="store_true", help="open the walkthrough at the end, where a display exists")
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
    from radiosity.formats import load_solution

    from .view import open_window

    solution = load_solution(out / "cornell-teapot" / "solution.npz")
    Walkthrough.configure(load_fit(out / "cornell-teapot" / "fit.npz"), solution,
                          solution.camera.sized(1280, 720), samples=samples)
    open_window()
