"""The fitting stage's subcommand: ``fit``."""

from __future__ import annotations

from pathlib import Path

from radiosity.formats.errors import InputError


def _lights(text):
    if text == "auto":
        return text
    try:
        return int(text)
    except ValueError:
        raise InputError(f"--lights takes a whole number or 'auto', got {text!r}") from None


def register(subparsers, not_built):
    p = subparsers.add_parser(
        "fit",
        help="fit virtual lights to a solution (fit.npz)",
        description="Fit a few virtual directional lights per glossy object so that the Phong "
        "shading formula reproduces the solution (Walter et al. 1997, section 3.2), then refine "
        "them (variable projection); writes Contract 2's fit.npz and prints each object's error.",
    )
    p.add_argument("solution", help="a solution.npz from 'vlights solve'")
    p.add_argument("-o", "--output", default="fit.npz", help="output file (default: %(default)s)")
    p.add_argument("--lights", default="8", metavar="K", help="lights per glossy object, or 'auto' (default: %(default)s)")
    p.add_argument("--target", type=float, default=0.1, metavar="E", help="relative RMS error target of --lights auto (default: %(default)s)")
    p.add_argument("--max-lights", type=int, default=16, metavar="N", help="most lights --lights auto may use (default: %(default)s)")
    p.add_argument("--method", choices=("paper", "refined", "per-light"), default="refined",
                   help="paper: section 3.2 exactly; refined: then non-linear refinement; per-light: refined with an exponent per light (default: %(default)s)")
    p.add_argument("--loss", choices=("linear", "relative"), default="linear",
                   help="error measure to minimise: linear least squares, or relative to the radiance (default: %(default)s)")
    p.add_argument("--exponent-bounds", type=float, nargs=2, default=(1.0, 1e4), metavar=("LOW", "HIGH"),
                   help="range of the exponent search (default: 1 10000)")
    p.add_argument("--iterations", type=int, default=100, metavar="N", help="refinement iterations (default: %(default)s)")
    p.set_defaults(func=_fit)


def _fit(args):
    from radiosity.cli import _output_path
    from radiosity.formats.solution import load_solution

    from .fit import FitOptions, fit

    out = _output_path(args.output)
    options = FitOptions(
        lights=_lights(args.lights), target=args.target, max_lights=args.max_lights, method=args.method,
        loss=args.loss, exponent_bounds=tuple(args.exponent_bounds), iterations=args.iterations,
    ).check()
    solution = load_solution(args.solution)
    model = fit(solution, options, progress=True)
    model.save(out)
    print(format_report(model, out))
    return 0


def format_report(model, path):
    """Per object: lights, exponents, error of the fit and of its diffuse part alone."""
    lines = [
        f"{'object':<14} {'K':>3} {'exponent(s)':<22} {'rel. RMS':>9} {'worst vertex':>13} {'diffuse only':>13} {'time':>7}"
    ]
    for o in model.objects:
        e = o.info["error"]
        exps = o.info["shininess"]
        shown = "-" if not exps else (f"{exps[0]:.4g}" if len(set(exps)) == 1 else f"{min(exps):.3g} .. {max(exps):.3g}")
        lines.append(
            f"{o.name:<14} {o.n_lights:>3} {shown:<22} {e['relative_rms']:>9.4f} {e['worst_vertex']:>13.4f} "
            f"{e['diffuse_only_relative_rms']:>13.4f} {o.info['time_s']:>6.2f}s"
        )
    size = Path(path).stat().st_size
    lines.append(f"wrote {path} ({size / 1e6:.2f} MB); method {model.settings['method']}, loss {model.settings['loss']}")
    return "\n".join(lines)
