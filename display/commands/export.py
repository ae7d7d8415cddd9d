"""``vlights export``: a fit as binary glTF with the WebGL walkthrough page beside it
(the writer: ``display.export``), optionally served at once (``display.serve``)."""

from __future__ import annotations

from display.export import FILE, PAGE, SHADING, page_files
from radiosity.files.errors import InputError


def add_command(subparsers):
    """``vlights export fit.npz -o DIR``: DIR/scene.glb."""
    p = subparsers.add_parser(
        "export",
        help="write a fitted model as binary glTF (DIR/scene.glb) with the WebGL walkthrough page beside it",
        description="Write fit.npz as DIR/scene.glb, binary glTF 2.0 for other viewers: each object's mesh, "
        "the fitted model's per-vertex arrays as float32 vertex attributes (_EMITTED, _SPECULAR or _SPECULAR_0 "
        ".., _PROBE, _VISIBILITY_0 .., a textured object's TEXCOORD_0, _IRRADIANCE and its image as the base "
        "colour texture), its lights, highlight and probe in the mesh's extras, the emitters, camera and "
        "environment in the scene's (the schema: docs/formats.md); and beside it the WebGL walkthrough "
        "(index.html, its script, the three.js modules and the shader files), which a browser opens through "
        "'vlights serve DIR' or --serve.",
    )
    p.add_argument("fit", help="fit.npz")
    p.add_argument("-o", "--out", required=True, metavar="DIR",
                   help=f"output directory, created if missing (not its parents); {FILE}, {PAGE} (the WebGL "
                   "walkthrough), the three.js modules and the shader files it loads are written into it")
    p.add_argument("--no-page", dest="page", action="store_false", help=f"write {FILE} alone")
    p.add_argument("--serve", action="store_true",
                   help="then serve DIR on 127.0.0.1 (as 'vlights serve DIR') and print the walkthrough's URL")
    p.add_argument("--port", type=int, default=8000, help="with --serve: TCP port, 0 for any free one (default: %(default)s)")
    p.set_defaults(func=run_export_command)


def _check_fit_file(path):
    """A fit.npz, or InputError in one line (missing, a directory, a solution.npz, another
    file): the one sniffer, ``radiosity.files.sniff.require_format``."""
    import os

    from radiosity.files.sniff import FIT, SOLUTION, input_kind, require_format

    if not os.path.isdir(path) and os.path.exists(path) and input_kind(path) == SOLUTION:
        raise InputError(f"input {str(path)!r} is a solution.npz, not a fit.npz (run 'vlights fit' on it first)")
    require_format(path, (FIT,), "input")


def run_export_command(args):
    from display.export import exported_mask, write_export
    from display.export_limits import check_export_memory, check_page_textures, fit_sizes
    from display.outputs import check_output_dir
    from fitting import load_fit

    _check_fit_file(args.fit)
    if args.serve and not args.page:
        raise InputError("--serve needs the page: drop --no-page")
    files = (FILE, SHADING, *(str(p) for p in page_files())) if args.page else (FILE,)
    out = check_output_dir(args.out, "-o", files=files, inputs=(args.fit,))
    sizes = fit_sizes(args.fit)  # from the array headers: the estimate and the page's textures before any work
    check_export_memory(sizes)
    if args.page:
        check_page_textures(sizes)
    model = load_fit(args.fit)
    glass = [o.name for o in model.objects if o.glass is not None or o.mirror is not None]
    if glass:  # the page has no glass or mirror shading yet: left out (vlights view and render draw them)
        from dataclasses import replace

        if len(glass) == len(model.objects):
            raise InputError(f"{args.fit}: every object is glass or a mirror, which the page does not draw yet")
        model = replace(model, objects=tuple(o for o in model.objects if o.glass is None and o.mirror is None))
        print(f"left out {len(glass)} glass object(s) and mirror(s) ({', '.join(glass[:4])}"
              f"{', ...' if len(glass) > 4 else ''}): the page does not draw them yet ('vlights view' and "
              "'vlights render' do)")
    server = None
    if args.serve:
        from display.serve import start

        server = start(out, args.port, must_exist=False)  # the port is had before anything is written
    try:
        path = write_export(model, out, page=args.page)
        lights = sum(o.n_lights for o in model.objects)
        extra = ""
        if model.emitters:
            highlights = sum(o.highlight is not None for o in model.objects)
            extra += f", {len(model.emitters)} emitter parts highlighted on {highlights} objects"
        probes = sum(o.probe is not None for o in model.objects)
        if probes:
            extra += f", {probes} reflection probes"
        textured = sum(o.textured is not None for o in model.objects)
        if textured:
            extra += f", {textured} textured"
        masked = [o.name for o in model.objects if o.textured is not None and o.textured.opacity is not None]
        exported = [name for name in masked if exported_mask(model.object(name)) is not None]
        if exported:
            extra += f", {len(exported)} masked"
        if model.environment is not None:
            h, w = model.environment.image.shape[:2]
            extra += ", a constant environment" if model.environment.constant else f", a {w} x {h} environment"
        print(f"wrote {path} ({len(model.objects)} objects, {lights} virtual lights{extra}, {path.stat().st_size} bytes)")
        if len(exported) < len(masked):
            left = [name for name in masked if name not in exported]
            print(f"left out the masks of {len(left)} object(s) ({', '.join(left[:4])}{', ...' if len(left) > 4 else ''}): "
                  "a mask the size of its texture is the image's alpha, and these differ; the page draws them opaque")
        if args.page:
            print(f"wrote {out / PAGE} (the walkthrough; open it through 'vlights serve {out}')")
        if server is not None:
            from display.serve import serve_until_interrupted

            serve_until_interrupted(server, out)
    finally:
        if server is not None:
            server.close()
    return 0
