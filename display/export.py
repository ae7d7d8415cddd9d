"""``vlights export``: a fitted model (fit.npz, Contract 2 version 2) as a binary glTF,
``DIR/scene.glb``, and a WebGL walkthrough of it, ``DIR/index.html`` (the page and the
three.js modules it needs, copied from ``display/web``: the directory works offline,
served by ``vlights serve DIR`` or any static server).

Schema (format ``vlights.fit.gltf``, version 1; the README's "Export" section):

- one glTF mesh (and one node, identity transform) per object of the fit, named as
  the object, in the fit's order; one triangle primitive with attributes
  ``POSITION`` (V, 3) float32, ``NORMAL`` (V, 3) float32 (the fit's normals as they
  are, not renormalised), indices = the fit's ``faces``, and the custom attributes

  - ``_EMITTED`` (V, 3) float32: the emitted colour;
  - ``_SPECULAR`` (V, 3) float32: the coefficient shared by all lights, or
    ``_SPECULAR_0`` .. ``_SPECULAR_{K-1}`` (V, 3) float32 each: the coefficient of
    light k, when the coefficients are per light. A diffuse object (K = 0) has
    ``_EMITTED`` alone (its specular part is 0);

  values are the fit's float32 bits, not clamped;
- the mesh's ``extras``: ``{"name", "lights": K, "per_light": bool, "light_pos":
  K x [x, y, z, w], "light_rgb": K x [r, g, b], "shininess": [K numbers]}``, with
  ``light_pos`` as in Contract 2 (w = 0: a unit vector towards a distant light, w = 1:
  a point light's world position);
- the scene's ``extras``: ``{"format": "vlights.fit.gltf", "version": 1, "source",
  "model", "objects": [names], "camera": {"eye", "look_at", "up", "fov_y_deg"}}``
  (``camera`` only when the fit has one, Contract 3).

The shading formula is Contract 2's (``fitting.model.shade_arrays``), with these
arrays. Written through trimesh's glTF exporter (``process=False``: vertices are not
merged, so no attribute value is lost) and moved into place only when complete.
``load_export`` reads the file back into a ``FittedModel``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from radiosity.formats import InputError

__all__ = ["FILE", "FORMAT", "PAGE", "SHADING", "VERSION", "add_export_command", "export_glb", "load_export", "page_files",
           "write_export", "write_files"]

FORMAT = "vlights.fit.gltf"
VERSION = 1
FILE = "scene.glb"
PAGE = "index.html"
WEB = Path(__file__).with_name("web")  # the page, its script and the vendored three.js (r187, MIT)


def page_files():
    """The walkthrough page's files, as paths relative to ``display/web`` (sorted)."""
    return sorted(p.relative_to(WEB) for p in WEB.rglob("*") if p.is_file() and "__pycache__" not in p.parts)


def vertex_attributes(obj):
    """The custom glTF attributes of one ``FittedObject``: name -> (V, 3) float32."""
    attributes = {"_EMITTED": np.asarray(obj.emitted, np.float32)}
    if obj.n_lights == 0:
        return attributes
    specular = np.asarray(obj.specular, np.float32)
    if obj.per_light:
        attributes.update({f"_SPECULAR_{k}": np.ascontiguousarray(specular[:, k]) for k in range(obj.n_lights)})
    else:
        attributes["_SPECULAR"] = specular
    return attributes


def _rows(a, width):
    """A float32 array as JSON lists of Python floats (exact: every float32 is a double)."""
    return np.asarray(a, np.float32).reshape(-1, width).astype(np.float64).tolist()


def mesh_extras(obj):
    """The mesh's ``extras``: the object's lights (JSON-ready)."""
    return {
        "name": obj.name,
        "lights": obj.n_lights,
        "per_light": bool(obj.per_light and obj.n_lights > 0),
        "light_pos": _rows(obj.light_pos, 4),
        "light_rgb": _rows(obj.light_rgb, 3),
        "shininess": np.asarray(obj.shininess, np.float32).reshape(-1).astype(np.float64).tolist(),
    }


def scene_extras(model):
    """The scene's ``extras``: format marker, provenance, object order, camera."""
    extras = {"format": FORMAT, "version": VERSION, "source": model.source, "model": model.model,
              "objects": list(model.names)}
    if model.camera is not None:
        extras["camera"] = {k: (np.asarray(v, np.float64).tolist() if k != "fov_y_deg" else float(v))
                            for k, v in model.camera.to_dict().items()}
    return extras


def export_glb(model):
    """The binary glTF (bytes) of a ``FittedModel``; schema in the module docstring."""
    import trimesh

    scene = trimesh.Scene(base_frame="vlights/root")  # an object name never holds a "/": no node clashes with it
    for obj in model.objects:
        mesh = trimesh.Trimesh(
            vertices=np.asarray(obj.positions, np.float32),
            faces=np.asarray(obj.faces, np.int64),
            vertex_normals=np.asarray(obj.normals, np.float32),
            vertex_attributes=vertex_attributes(obj),
            metadata=mesh_extras(obj),
            process=False,
            validate=False,
        )
        scene.add_geometry(mesh, geom_name=obj.name, node_name=obj.name)
    scene.metadata.update(scene_extras(model))
    return trimesh.exchange.gltf.export_glb(scene, include_normals=True, unitize_normals=False)


SHADING = "shading.js"  # written with the page: the renderer's shading GLSL as an ES module


def shading_module():
    """``shading.js``: display.renderer's SHADE_GLSL (the shading formula the page and
    ``vlights render`` share) and its coefficient texture width, as JavaScript."""
    from display.renderer import FLOAT_TEXTURE_WIDTH, SHADE_GLSL

    return ("// Written by `vlights export` from display/renderer.py: the renderer's shading code.\n"
            f"export const SHADE_GLSL = {json.dumps(SHADE_GLSL)};\n"
            f"export const TEXTURE_WIDTH = {FLOAT_TEXTURE_WIDTH};\n")


def write_files(model, directory, page=True):
    """Write scene.glb and, with ``page``, the walkthrough page into ``directory`` (which
    exists); no staging: for callers that stage a whole run (``write_export``, the demo).
    Returns the path of scene.glb."""
    import shutil

    directory = Path(directory)
    (directory / FILE).write_bytes(export_glb(model))
    for name in page_files() if page else ():
        (directory / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(WEB / name, directory / name)
    if page:
        (directory / SHADING).write_text(shading_module())
    return directory / FILE


def write_export(model, out, page=True):
    """Write ``out/scene.glb`` and, with ``page``, the walkthrough page beside it
    (``out`` is created if missing, not its parents); the files appear complete or not
    at all. Returns the path of scene.glb."""
    from display.outputs import staged_directory

    out = Path(out)
    with staged_directory(out) as stage:
        write_files(model, stage, page)
    return out / FILE


def _chunks(path):
    """The JSON header of a .glb file (a dict); InputError if it is not one."""
    data = Path(path).read_bytes()
    if len(data) < 20 or data[:4] != b"glTF":
        raise InputError(f"{str(path)!r} is not a binary glTF file")
    length = int.from_bytes(data[12:16], "little")
    return json.loads(data[20:20 + length])


def load_export(path):
    """Read a ``scene.glb`` written by ``export_glb`` back into a ``FittedModel``
    (arrays float32 / int32 as in ``fitting.model``; a diffuse object's specular is
    zeros (V, 3)). InputError if the file is not of this schema."""
    import trimesh

    from fitting.model import FittedModel, FittedObject
    from radiosity.formats.camera import camera_from_dict

    header = _chunks(path)
    extras = (header.get("scenes") or [{}])[0].get("extras") or {}
    if extras.get("format") != FORMAT or extras.get("version") != VERSION:
        raise InputError(f"{str(path)!r} is not a {FORMAT} version {VERSION} file")
    scene = trimesh.load(path, file_type="glb", force="scene", process=False)
    objects = []
    for name in extras["objects"]:
        mesh = scene.geometry[name]
        info = mesh.metadata
        k = int(info["lights"])
        v = len(mesh.vertices)
        attributes = mesh.vertex_attributes
        if k == 0:
            specular = np.zeros((v, 3), np.float32)
        elif info["per_light"]:
            specular = np.stack([np.asarray(attributes[f"_SPECULAR_{i}"], np.float32) for i in range(k)], axis=1)
        else:
            specular = np.asarray(attributes["_SPECULAR"], np.float32)
        objects.append(FittedObject(
            name=name,
            positions=np.asarray(mesh.vertices, np.float32),
            normals=np.asarray(mesh.vertex_normals, np.float32),
            faces=np.asarray(mesh.faces, np.int32),
            emitted=np.asarray(attributes["_EMITTED"], np.float32),
            specular=specular,
            light_pos=np.asarray(info["light_pos"], np.float32).reshape(k, 4),
            light_rgb=np.asarray(info["light_rgb"], np.float32).reshape(k, 3),
            shininess=np.asarray(info["shininess"], np.float32).reshape(k),
        ))
    camera = camera_from_dict(extras["camera"], where="scene extras 'camera'") if "camera" in extras else None
    return FittedModel(objects=tuple(objects), source=extras.get("source", ""), model=extras.get("model", ""),
                       camera=camera)


def add_export_command(subparsers):
    """``vlights export fit.npz -o DIR``: DIR/scene.glb."""
    p = subparsers.add_parser(
        "export",
        help="write a fitted model as a binary glTF (DIR/scene.glb) for other viewers",
        description="Write fit.npz as DIR/scene.glb: per object its mesh (positions, normals, faces), the emitted "
        "colour as the vertex attribute _EMITTED and the specular coefficients as _SPECULAR (shared by the "
        "lights) or _SPECULAR_0 .. _SPECULAR_{K-1} (one per light), float32 as in the fit; the object's lights "
        "(light_pos, light_rgb, shininess, per_light) in the mesh's extras; the format marker and the scene "
        "camera in the scene's extras.",
    )
    p.add_argument("fit", help="fit.npz")
    p.add_argument("-o", "--out", required=True, metavar="DIR",
                   help=f"output directory, created if missing (not its parents); {FILE}, {PAGE} (the WebGL "
                   "walkthrough) and the three.js modules it loads are written into it")
    p.add_argument("--no-page", dest="page", action="store_false", help=f"write {FILE} alone")
    p.add_argument("--serve", action="store_true",
                   help="then serve DIR on 127.0.0.1 (as 'vlights serve DIR') and print the walkthrough's URL")
    p.add_argument("--port", type=int, default=8000, help="with --serve: TCP port, 0 for any free one (default: %(default)s)")
    p.set_defaults(func=run_export_command)


def _check_fit_file(path):
    """A fit.npz, or InputError in one line (missing, a directory, a solution.npz, another file)."""
    import os

    from radiosity.formats import file_format

    shown = str(path)
    if not os.path.exists(path):
        raise InputError(f"input {shown!r} not found")
    if os.path.isdir(path):
        raise InputError(f"input {shown!r} is a directory, not a fit.npz")
    fmt = file_format(path)
    if fmt == "vlights.solution":
        raise InputError(f"input {shown!r} is a solution.npz, not a fit.npz (run 'vlights fit' on it first)")
    if fmt != "vlights.fit":
        found = f"an .npz file of format {fmt!r}" if fmt is not None else "not one of this program's .npz files"
        raise InputError(f"input {shown!r} is not a fit.npz: it is {found}")


def run_export_command(args):
    from display.outputs import check_output_dir
    from fitting import load_fit

    _check_fit_file(args.fit)
    if args.serve and not args.page:
        raise InputError("--serve needs the page: drop --no-page")
    files = (FILE, SHADING, *(str(p) for p in page_files())) if args.page else (FILE,)
    out = check_output_dir(args.out, "-o", files=files, inputs=(args.fit,))
    model = load_fit(args.fit)
    server = None
    if args.serve:
        from display.serve import start

        server = start(out, args.port, must_exist=False)  # the port is had before anything is written
    try:
        path = write_export(model, out, page=args.page)
        lights = sum(o.n_lights for o in model.objects)
        print(f"wrote {path} ({len(model.objects)} objects, {lights} virtual lights, {path.stat().st_size} bytes)")
        if args.page:
            print(f"wrote {out / PAGE} (the walkthrough; open it through 'vlights serve {out}')")
        if server is not None:
            from display.serve import serve_until_interrupted

            serve_until_interrupted(server, out)
    finally:
        if server is not None:
            server.close()
    return 0
