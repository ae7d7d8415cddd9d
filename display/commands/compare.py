"""``vlights compare``: the paper's figures 5-7 as PNG files with FLIP error images, and
their numbers in compare.json (``display.compare``), optionally against path-traced
truths of figure 5's views, or against an external reference image (``--reference``:
another renderer's HDR picture at the scene's camera)."""

from __future__ import annotations

import os

from display.gl import check_sample_count
from radiosity.files.errors import InputError
from radiosity.policies.limits import check_exposure, check_seed

from .common import (
    FIT,
    SOLUTION,
    add_camera_flags,
    add_glass_flag,
    add_samples_flag,
    check_drawable,
    headless,
    input_format,
    resolve_view,
)

__all__ = ["add_command", "run"]


def add_command(subparsers):
    from display.choices import ORBIT_DEGREES

    p = subparsers.add_parser(
        "compare",
        help="the paper's figures 5-7 with FLIP error images and numbers, optionally against a path-traced "
        "truth or another renderer's image",
        description="The paper's figures as PNG files into --out, each with a FLIP error image against the "
        "solution display (the solution drawn directly, what the model was fitted to): 5, the solution display "
        "against the fitted display from three viewpoints (the scene's camera and it turned "
        f"{ORBIT_DEGREES:g} degrees each way about its look-at point); 6, 2 virtual lights against all; 7, the fitted display against a diffuse walkthrough. Their "
        "FLIP, PSNR and relative MSE, over the whole image and the glossy objects alone, go into compare.json "
        "and a table on stdout. With --truth or --truth-spp every display is also measured against a "
        "path-traced truth; with --reference, against another renderer's image.",
    )
    p.add_argument("fit", help="fit.npz")
    p.add_argument("solution", help="the solution.npz it was fitted to")
    p.add_argument("--out", default="compare", metavar="DIR", help="output directory, created if missing (default: %(default)s)")
    add_camera_flags(p, (512, 512))
    p.add_argument("--exposure", type=float, default=1.0, help="multiplies radiance before sRGB (default: %(default)s)")
    p.add_argument("--shading", choices=("gouraud", "pixel"), default="pixel",
                   help="gouraud: per vertex, as in 1997; pixel: per pixel (default: %(default)s)")
    add_samples_flag(p)
    add_glass_flag(p)
    p.add_argument("--truth", nargs="+", metavar="FILE.npy",
                   help="path-traced images of figure 5's views, in order (from 'vlights truth --hdr' with the same "
                   "camera and size): every display is also measured against them")
    p.add_argument("--truth-spp", type=int, default=0, metavar="N",
                   help="path-trace the truth of every view without a --truth file, N samples per pixel (default: none)")
    p.add_argument("--seed", type=int, default=1, help="the path tracer's seed, with --truth-spp (default: %(default)s)")
    p.add_argument("--reference", metavar="IMAGE",
                   help="an image of the scene from its camera (or the camera flags'), linear radiance as OpenEXR "
                   ".exr, Radiance .hdr, .pfm or .npy, e.g. another renderer's: the solution, fitted and diffuse "
                   "displays and, with --truth-spp (which then traces this view alone), the path tracer are measured "
                   "against it at its own size (FLIP, relative MSE, mean ratio), into compare.json and reference/; "
                   "--size may only shrink it by a whole factor; not with --truth")
    p.set_defaults(func=run, size=None)  # None: 512x512, or the --reference image's own size


def check_inputs(fit_path, solution_path):
    """compare takes a fit.npz, then a solution.npz: say so plainly when they are swapped."""
    fmt_fit = input_format(fit_path, (FIT, SOLUTION), "the fit")
    fmt_solution = input_format(solution_path, (FIT, SOLUTION), "the solution")
    if fmt_fit == SOLUTION and fmt_solution == FIT:
        raise InputError(f"the files are the wrong way round: {str(fit_path)!r} is a solution.npz and "
                         f"{str(solution_path)!r} a fit.npz; give the fit.npz first")
    if fmt_fit != FIT:
        raise InputError(f"the fit {str(fit_path)!r} is a solution.npz, not a fit.npz (compare takes a fit.npz, then "
                         "the solution.npz it was fitted to)")
    if fmt_solution != SOLUTION:
        raise InputError(f"the solution {str(solution_path)!r} is a fit.npz, not a solution.npz (compare takes a "
                         "fit.npz, then the solution.npz it was fitted to)")


def check_truth_flags(args):
    """--truth files (at most one per view, .npy, existing) and --truth-spp, before any work."""
    from display.pipeline import check_spp

    files = args.truth or []
    if len(files) > 3:
        raise InputError(f"--truth takes at most 3 files (one per view of figure 5), got {len(files)}")
    for path in files:
        if not str(path).endswith(".npy"):
            raise InputError(f"--truth {path!r} must be an .npy file (from 'vlights truth --hdr')")
        if not os.path.isfile(path):
            raise InputError(f"--truth {path!r} not found")
    check_spp(args.truth_spp, "--truth-spp", low=0)
    check_seed(args.seed)


def read_reference(args):
    """The --reference image at the size the renders take (``args.size`` or its own), and
    the factor it was shrunk by; every refusal before any work."""
    from display.compare import reference_at
    from display.images import read_hdr_image
    from display.metrics import BLACK, is_black

    if args.truth:
        raise InputError("--reference and --truth exclude each other: --truth gives path-traced images of figure 5's "
                         "views, --reference one image of the scene's view; add --truth-spp N to path-trace that view")
    image = read_hdr_image(args.reference, "--reference")
    if is_black(image):
        raise InputError(f"--reference {str(args.reference)!r} {BLACK}")
    return reference_at(image, args.size, f"--reference {str(args.reference)!r}")


def check_reference_camera(args, fit, solution):
    """--reference's image is taken with the scene's camera (the solution's meta.camera)
    or the one the flags give: refuse a framing view, which no outside image was taken with."""
    scene_camera = any(getattr(m, "camera", None) is not None for m in (solution, fit))
    if not scene_camera and args.view is None and not (args.eye and args.look_at):
        raise InputError(f"--reference {str(args.reference)!r}: the solution has no camera (meta.camera) to render the "
                         "image's view with; give the camera it was taken with: --eye, --look-at (--up, --fov), "
                         "or --view NAME --views FILE")


def truths_for(args, solution, views):
    """Per view: the --truth file's image, else (with --truth-spp) a path-traced one, else None."""
    from display.truth import GroundTruth, ground_truth, load_truth

    files = args.truth or []
    truths = []
    for i, view in enumerate(views):
        if i < len(files):
            truths.append(GroundTruth(load_truth(files[i], view), 0, None, {"file": files[i]}))
        elif args.truth_spp:
            print(f"path-tracing the truth of view {i + 1} ({args.truth_spp} samples per pixel)")
            truths.append(ground_truth(solution, view, args.truth_spp, args.seed, progress=True))
        else:
            truths.append(None)
    return truths


def run(args):
    from display.compare import FILES, ReferenceImage, compare, figure5_views, reference_files
    from display.gl import COMPARE_BYTES_PER_PIXEL
    from display.outputs import check_output_dir
    from display.renderer import Renderer
    from fitting import load_fit
    from radiosity.files.solution import load_solution

    check_exposure(args.exposure)
    check_sample_count(args.samples)
    check_truth_flags(args)
    check_inputs(args.fit, args.solution)
    image = factor = None
    if args.reference is not None:
        image, factor = read_reference(args)
        args.size = (image.shape[1], image.shape[0])
    elif args.size is None:
        args.size = (512, 512)
    files = FILES + (reference_files(args.truth_spp > 0) if image is not None else ())
    out = check_output_dir(args.out, "--out", files=files, inputs=(args.fit, args.solution, args.reference))
    with headless(args.size, args.samples, COMPARE_BYTES_PER_PIXEL) as ctx:
        fit, solution = load_fit(args.fit), check_drawable(load_solution(args.solution), args.solution)
        if image is not None:
            check_reference_camera(args, fit, solution)
        renderer = Renderer(ctx, fit=fit, solution=solution, samples=args.samples)
        renderer.glass_approach = args.glass
        renderer.near_mirrors = args.near_mirrors
        view = resolve_view(args, renderer.bounds, fit, solution)
        views = figure5_views(view)
        reference = None if image is None else ReferenceImage(image, view, str(args.reference), factor)
        truths = truths_for(args, solution, views[:1] if reference is not None else views)
        results = compare(renderer, out, view, args.exposure, args.shading, views=views, truths=truths,
                          reference_image=reference)
        renderer.release()
    print_results(results, args.samples, out)
    return 0


def _row(m):
    glossy = (f"{m['flip_mean_glossy']:>8.4f} {m['psnr_db_glossy']:>8.2f} {m['relative_mse_glossy']:>10.4g}"
              if "flip_mean_glossy" in m else "")
    return f"{m['flip_mean']:>8.4f} {m['psnr_db']:>8.2f} {m['relative_mse']:>10.4g} {glossy}"


def print_results(results, samples, out):
    """The table of compare.json's numbers, on stdout."""
    from display.compare import DISPLAY_LABELS

    print(f"wrote figures 5, 6, 7 and compare.json to {out}/ ({samples} samples per pixel)")
    print(f"  {'':<32} {'whole image':^28} {'glossy objects only':^28}")
    print(f"  {'':<32} {'FLIP':>8} {'PSNR dB':>8} {'rel.MSE':>10} {'FLIP':>8} {'PSNR dB':>8} {'rel.MSE':>10}")
    rows = [(f"figure 5, view {i}", results["figure5"][f"view{i}"]) for i in range(1, 4)]
    rows += [(f"figure 6, {k.replace('_', ' ')}", m) for k, m in results["figure6"].items()]
    rows += [(f"figure 7, {k.replace('_', ' ')}", m) for k, m in results["figure7"].items() if isinstance(m, dict)]
    for label, m in rows:
        print(f"  {label:<32} {_row(m)}")
    if any(m[k] == float("inf") for _, m in rows for k in ("psnr_db", "psnr_db_glossy") if k in m):
        print("  (PSNR inf: the pictures are identical; compare.json has null there, explained in its notes)")
    for name, t in results.get("truth", {}).items():
        noise = "" if t["noise_flip"] is None else f", noise floor FLIP {t['noise_flip']:.4f}"
        source = f"{t['spp']} spp" if t["spp"] else "from a file"
        print(f"  against the path-traced truth, {name.replace('view', 'view ')} ({source}{noise}):")
        for mode in ("reference", "fitted", "diffuse"):
            print(f"    {DISPLAY_LABELS[mode]:<30} {_row(t[mode])}")
    if "reference_image" in results:
        print_reference(results["reference_image"], out)


def print_reference(numbers, out):
    """The table of compare.json's "reference_image", on stdout."""
    from display.compare import DISPLAY_LABELS

    shrunk = f", box-averaged by {numbers['downsampled_by']}" if numbers["downsampled_by"] > 1 else ""
    print(f"  against the reference image {numbers['file']} ({numbers['width']}x{numbers['height']}{shrunk}); "
          f"renders and FLIP images in {out}/reference/:")
    print(f"    {'':<30} {'FLIP':>8} {'rel.MSE':>10} {'mean ratio':>11}")
    for mode, m in numbers["displays"].items():
        label = f"path tracer ({m.get('spp')} spp)" if mode == "path_tracer" else DISPLAY_LABELS[mode]
        noise = "" if m.get("noise_flip") is None else f"   (its noise floor: FLIP {m['noise_flip']:.4f})"
        print(f"    {label:<30} {m['flip_mean']:>8.4f} {m['relative_mse']:>10.4g} {m['mean_ratio']:>11.4f}{noise}")
