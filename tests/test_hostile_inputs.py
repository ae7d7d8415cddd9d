"""Hostile inputs to ``scene-info``, ``solve`` and ``fit``: every one ends in one line
naming the problem and exit status 2 (or a clear warning), no traceback, nothing
half-written or clobbered, nothing left in the temporary directory.

The first part holds the defects an adversarial sweep found, each with the input that
showed it; the second is this sweep's own: malformed scenes and archives, names with
control characters, output-path hazards and the extremes of every numeric flag.
Commands run in this process (``display.cli.main``) unless they need a child
(``subprocess`` marker).
"""

import json
import os
import stat
import subprocess
import sys
import threading
import warnings
from pathlib import Path

import numpy as np
import pytest
from bad_inputs import GOOD_MATERIAL, npy_bytes, replace_member, tiny_solution, write
from refusals import assert_refused

from display.cli import main
from radiosity.files.camera import load_views
from radiosity.files.errors import InputError, SceneWarning
from radiosity.files.inputs import MAX_NESTING, check_input_file, read_input_bytes
from radiosity.files.npz import write_archive
from radiosity.files.sniff import FIT, SOLUTION, input_kind, require_format
from radiosity.files.solution import load_solution
from radiosity.scene.loaders import load_scene, safe_object_name

CUBE = "[[objects]]\nname = {name}\nbuiltin = 'cube'\nmaterial = 'm'\n"
GLOSSY = """
[materials.shiny]
diffuse = 0.2
specular = 0.5
exponent = 20
[materials.lamp]
emission = 5.0
[[objects]]
name = "floor"
builtin = "quad"
material = "shiny"
scale = 2
[[objects]]
name = "lamp"
builtin = "quad"
material = "lamp"
translate = [0, 1, 0]
rotate_deg = [180, 0, 0]
"""


def run(argv, capsys):
    """(exit status, stdout, stderr) of ``vlights argv``; a parse error's SystemExit too."""
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def refused(argv, capsys, fragment=""):
    return assert_refused(run(argv, capsys), fragment, quiet=False)


@pytest.fixture
def solution(tmp_path):
    return tiny_solution(tmp_path / "solution.npz")


@pytest.fixture(autouse=True)
def no_temporary_files_left(tmp_path):
    """Nothing of ours (a ``.<name>.<hex>.tmp``) is left in the test's directory."""
    yield
    left = [p for p in tmp_path.rglob(".*.tmp")]
    assert not left, left


# -- the defects the sweep found ----------------------------------------------------


@pytest.mark.parametrize("char", ["\x00", "\x01", "\n", "\x1b", "\x7f", "\x85"])
def test_object_names_with_control_characters_are_refused_when_read(char, tmp_path, capsys):
    # a NUL used to solve and write members cut at the NUL, which fit then refused
    name = json.dumps("lamp" + char + "shade")  # a TOML basic string, escapes as JSON's
    path = write(tmp_path / "scene.toml", GOOD_MATERIAL + CUBE.format(name=name))
    with pytest.raises(InputError, match=rf"object 'lamp.*shade'.*control characters \(U\+{ord(char):04X}\)"):
        load_scene(path)
    err = refused(["solve", path, "-o", tmp_path / "s.npz"], capsys, "control characters")
    assert "lamp" in err and not (tmp_path / "s.npz").exists()


@pytest.mark.parametrize("key", ["a\x00b/radiance", "a\nb/x", "\udc80/x"])
def test_the_npz_writer_refuses_names_it_cannot_keep(key, tmp_path):
    with pytest.raises(ValueError, match="array name"):
        write_archive(tmp_path / "a.npz", {"format": "x", "version": 1}, {key: np.zeros(3)})
    assert list(tmp_path.iterdir()) == []


def test_mesh_node_names_are_made_safe():
    assert safe_object_name("a\x00b/c\nd") == "a_b_c_d"
    assert safe_object_name("teapot.001") == "teapot.001"


def test_a_solution_object_named_with_a_nul_is_refused(tmp_path):
    with pytest.raises(ValueError, match="control character U\\+0000"):
        tiny_solution(tmp_path / "s.npz", name="a\x00b")
    assert list(tmp_path.iterdir()) == []


def test_a_249_character_output_passes_the_check(tmp_path, capsys, monkeypatch):
    # used to be refused only after the whole solve: the temporary name was 18 longer
    from radiosity.files.atomic import check_output

    monkeypatch.chdir(tmp_path)
    check_output("s" * 245 + ".npz", ".npz")
    refused(["solve", "cornell", "-o", "s" * 252 + ".npz"], capsys, "256 bytes long, more than the 255")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("value", ["1000", "1e9", "-1", "65", "nan", "inf"])
def test_kernel_rings_are_bounded_at_parse_time(value, tmp_path, capsys):
    # 1000 rings ended the solve in NaN; 10^9 rings did not end in 180 s
    refused(["solve", "cornell", "-o", tmp_path / "s.npz", "--kernel-rings", value], capsys, "--kernel-rings")
    assert list(tmp_path.iterdir()) == []


def _unblock_fifo_later(path, seconds=10.0):
    """Should a reader block on the FIFO (the defect), open it for writing after a
    while so the test fails instead of hanging."""

    def release():
        try:
            fd = os.open(path, os.O_WRONLY | os.O_NONBLOCK)
            os.close(fd)
        except OSError:
            pass

    timer = threading.Timer(seconds, release)
    timer.daemon = True
    timer.start()
    return timer


@pytest.fixture(params=["fifo", "dev-zero", "directory", "dangling"])
def not_a_file(request, tmp_path):
    """(kind, a function making that at a path)."""
    kind = request.param

    def make(path):
        if kind == "fifo":
            os.mkfifo(path)
            _unblock_fifo_later(path)
        elif kind == "dev-zero":
            path.symlink_to("/dev/zero")
        elif kind == "directory":
            path.mkdir()
        else:
            path.symlink_to(tmp_path / "nothing-here")
        return path

    return kind, make


EXPECTED = {"fifo": "named pipe", "dev-zero": "character device", "directory": "directory", "dangling": "symlink to nothing"}


@pytest.mark.parametrize("name", ["scene.toml", "mesh.obj", "mesh.glb"])
def test_scenes_that_are_not_regular_files_are_refused_before_reading(name, not_a_file, tmp_path, capsys):
    kind, make = not_a_file
    path = make(tmp_path / name)
    with pytest.raises(InputError, match=EXPECTED[kind]):
        load_scene(path)
    refused(["scene-info", path], capsys, EXPECTED[kind])


def test_a_toml_mesh_that_is_a_device_is_refused(tmp_path):
    (tmp_path / "zero.obj").symlink_to("/dev/zero")
    path = write(tmp_path / "scene.toml", GOOD_MATERIAL + "[[objects]]\nname='a'\nmesh='zero.obj'\nmaterial='m'\n")
    with pytest.raises(InputError, match="character device"):
        load_scene(path)


def test_solution_and_views_that_are_not_regular_files_are_refused(not_a_file, tmp_path, capsys):
    kind, make = not_a_file
    path = make(tmp_path / "solution.npz")
    refused(["fit", path, "-o", tmp_path / "f.npz"], capsys, EXPECTED[kind])
    with pytest.raises(InputError, match=EXPECTED[kind]):
        load_solution(path)
    views = make(tmp_path / "views.json")
    with pytest.raises(InputError, match=EXPECTED[kind]):
        load_views(views)


def test_files_beyond_their_kinds_size_are_refused(tmp_path):
    big = tmp_path / "scene.toml"
    with open(big, "wb") as f:  # sparse: no disk used
        f.truncate(65 * 2**20)
    with pytest.raises(InputError, match="65 MiB, more than the 64 MiB a scene may be"):
        load_scene(big)
    small = tmp_path / "a.txt"
    small.write_bytes(b"x" * 100)
    with pytest.raises(InputError, match="more than the 99 bytes"):
        read_input_bytes(small, "file", 99)
    assert check_input_file(small, "file", 100) == str(small)


def test_an_npz_header_claiming_10_to_the_12_rows_is_refused_before_allocating(solution, tmp_path, capsys):
    replace_member(solution, "plate/radiance.npy", npy_bytes((10**12, 1, 3), "<f4", b"\0" * 64))
    with pytest.raises(InputError, match=r"'plate/radiance' claims shape \(1000000000000, 1, 3\).*but stores 64 bytes"):
        load_solution(solution)
    refused(["fit", solution, "-o", tmp_path / "f.npz"], capsys, "claims shape")
    assert not (tmp_path / "f.npz").exists()


def test_an_npz_meta_claiming_terabytes_is_refused(solution, tmp_path, capsys):
    from fitting import load_fit

    replace_member(solution, "meta.npy", npy_bytes((10**12,), "<U10"))
    for reader in (load_solution, load_fit):
        with pytest.raises(InputError, match="'meta' claims shape"):
            reader(solution)
    assert input_kind(solution) == "npz"  # not ours: the sniffer does not read it either


def test_an_npz_member_beyond_the_free_memory_is_refused(solution, monkeypatch):
    import radiosity.files.npz as npz

    monkeypatch.setattr(npz, "available_memory", lambda: 100)
    with pytest.raises(InputError, match="needs .* of memory, more than the 100 bytes available"):
        load_solution(solution)


DEEP = 100_000


@pytest.mark.parametrize("depth", [MAX_NESTING + 5, DEEP])
def test_documents_nested_too_deep_are_one_line(depth, tmp_path, capsys):
    toml = write(tmp_path / "deep.toml", "x = " + "[" * depth + "]" * depth + "\n")
    with pytest.raises(InputError, match="nested too deep"):
        load_scene(toml)
    refused(["scene-info", toml], capsys, "nested too deep")

    views = tmp_path / "views.json"
    views.write_text('{"a": ' + "[" * depth + "]" * depth + "}")
    with pytest.raises(InputError, match="views file .* nested too deep"):
        load_views(views)

    gltf = tmp_path / "deep.gltf"
    gltf.write_text('{"asset": {"version": "2.0"}, "extras": ' + "[" * depth + "]" * depth + "}")
    with pytest.raises(InputError, match="nested too deep"):
        load_scene(gltf)


def test_npz_meta_nested_too_deep_is_one_line(solution, tmp_path, capsys):
    meta = '{"format": "vlights.solution", "version": 2, "x": ' + "[" * DEEP + "]" * DEEP + "}"
    buf = __import__("io").BytesIO()
    np.save(buf, np.array(meta))
    replace_member(solution, "meta.npy", buf.getvalue())
    with pytest.raises(InputError, match="'meta': nested too deep"):
        load_solution(solution)
    refused(["fit", solution, "-o", tmp_path / "f.npz"], capsys, "")


def _obj_with_mtl(tmp_path, texture, uvs=False):
    (tmp_path / "m.mtl").write_text(f"newmtl red\nKd 0.8 0.1 0.1\nmap_Kd {texture}\n")
    if uvs:  # a texture needs texture coordinates (without them it counts with its mean colour, and says so)
        return write(tmp_path / "a.obj", "mtllib m.mtl\nusemtl red\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                     "vt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n")
    return write(tmp_path / "a.obj", "mtllib m.mtl\nusemtl red\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")


def test_an_mtl_naming_a_missing_texture_warns(tmp_path):
    path = _obj_with_mtl(tmp_path, "wood.png")
    with pytest.warns(SceneWarning, match="material library 'm.mtl' names the texture 'wood.png', which is not found"):
        scene = load_scene(path)
    assert scene.objects[0].material.diffuse[0] == pytest.approx(0.8)


def test_an_mtl_whose_texture_exists_does_not_warn(tmp_path):
    from PIL import Image

    Image.new("RGB", (2, 2), (255, 255, 255)).save(tmp_path / "white.png")
    path = _obj_with_mtl(tmp_path, "white.png", uvs=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error", SceneWarning)
        scene = load_scene(path)
    assert scene.objects[0].texture is not None


@pytest.mark.parametrize("uvs", [True, False])
def test_a_truncated_mtl_texture_is_refused_in_one_line(tmp_path, capsys, uvs):
    """A held-out input: the PNG's first half ended in pillow's OSError (read as a texture,
    or for its mean colour on a mesh without texture coordinates)."""
    from PIL import Image

    Image.fromarray((np.random.default_rng(1).random((64, 64, 3)) * 255).astype(np.uint8)).save(tmp_path / "t.png")
    whole = (tmp_path / "t.png").read_bytes()
    (tmp_path / "t.png").write_bytes(whole[:len(whole) // 2])
    code, _, err = run(["scene-info", _obj_with_mtl(tmp_path, "t.png", uvs=uvs)], capsys)
    assert code == 2 and err.count("\n") == 1, err
    assert "material 'red': texture: cannot read the image: image file is truncated" in err


def test_a_truncated_gltf_texture_is_refused_in_one_line(tmp_path, capsys):
    import trimesh
    from PIL import Image

    Image.fromarray((np.random.default_rng(1).random((64, 64, 3)) * 255).astype(np.uint8)).save(tmp_path / "t.png")
    mesh = trimesh.Trimesh(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0]], faces=[[0, 1, 2]], process=False)
    material = trimesh.visual.material.PBRMaterial(name="tex", baseColorTexture=Image.open(tmp_path / "t.png"))
    mesh.visual = trimesh.visual.TextureVisuals(uv=[[0, 0], [1, 0], [0, 1]], material=material)
    data = mesh.export(file_type="glb")
    start, end = data.find(b"\x89PNG"), data.find(b"IEND")
    half = start + (end - start) // 2
    (tmp_path / "t.glb").write_bytes(data[:half] + bytes(end - half) + data[end:])
    code, _, err = run(["scene-info", tmp_path / "t.glb"], capsys)
    assert code == 2 and err.count("\n") == 1, err
    assert "material 'tex': texture: cannot read the image" in err


def _png_header(width, height):
    """A PNG's signature and IHDR (8-bit RGB) and an empty IEND: a picture's size, no pixels."""
    import struct
    import zlib

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)) + chunk(b"IEND", b"")


@pytest.mark.parametrize("content, why", [(b"hello, I am text", "is not an image this reads"),
                                          (_png_header(20000, 20000), "is a picture of more than the 67,108,864")])
def test_an_mtl_texture_that_is_no_usable_image_warns(tmp_path, content, why):
    """Held-out inputs: a text file named .png, and a 20000 x 20000 PNG ("bomb"), were
    dropped by trimesh without a word. A picture pillow opens but too large for a
    texture is refused in one line, as a scene's texture is."""
    (tmp_path / "t.png").write_bytes(content)
    with pytest.warns(SceneWarning, match=f"the image 't.png' it names {why}"):
        scene = load_scene(_obj_with_mtl(tmp_path, "t.png", uvs=True))
    assert scene.objects[0].texture is None and scene.objects[0].material.diffuse[0] == pytest.approx(0.8)
    (tmp_path / "t.png").write_bytes(_png_header(9000, 9000))
    with pytest.raises(InputError, match="the texture is 9000 x 9000 pixels, more than the 67,108,864 allowed"):
        load_scene(_obj_with_mtl(tmp_path, "t.png", uvs=True))


@pytest.mark.parametrize("image, why", [("missing.png", "is not found"), ("text.png", "is not an image this reads")])
def test_a_gltf_image_that_is_missing_or_no_image_warns(tmp_path, image, why):
    """A held-out input: a glTF's missing texture was dropped without a word."""
    import trimesh
    from PIL import Image

    Image.new("RGB", (4, 4)).save(tmp_path / "ok.png")
    (tmp_path / "text.png").write_text("hello, I am text")
    mesh = trimesh.Trimesh(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0]], faces=[[0, 1, 2]], process=False)
    material = trimesh.visual.material.PBRMaterial(name="tex", baseColorTexture=Image.open(tmp_path / "ok.png"))
    mesh.visual = trimesh.visual.TextureVisuals(uv=[[0, 0], [1, 0], [0, 1]], material=material)
    files = mesh.export(file_type="gltf")
    for name, data in files.items():
        (tmp_path / name).write_bytes(data if isinstance(data, bytes) else data.encode())
    tree = json.loads((tmp_path / "model.gltf").read_text())
    tree["images"][0] = {"uri": image}
    (tmp_path / "model.gltf").write_text(json.dumps(tree))
    with pytest.warns(SceneWarning, match=f"the image '{image}' it names {why}"):
        load_scene(tmp_path / "model.gltf")


def test_a_texture_that_is_a_fifo_is_refused_not_waited_for(tmp_path):
    os.mkfifo(tmp_path / "wood.png")
    _unblock_fifo_later(tmp_path / "wood.png")
    with pytest.raises(InputError, match="named pipe"):
        load_scene(_obj_with_mtl(tmp_path, "wood.png"))


# -- the one sniffer ------------------------------------------------------------------


def test_the_sniffer_names_every_kind(solution, tmp_path):

    write(tmp_path / "s.toml", GOOD_MATERIAL)
    write(tmp_path / "m.obj", "v 0 0 0\n")
    np.save(tmp_path / "a.npy", np.zeros(2))
    np.savez(tmp_path / "other.npz", x=np.zeros(2))
    (tmp_path / "notes.txt").write_text("hello")
    renamed = tmp_path / "renamed.bin"
    renamed.write_bytes(solution.read_bytes())
    write_archive(tmp_path / "fit.npz", {"format": FIT, "version": 1}, {})
    kinds = {p: input_kind(tmp_path / p) for p in
             ("s.toml", "m.obj", "a.npy", "other.npz", "notes.txt", "renamed.bin", "solution.npz", "fit.npz")}
    assert kinds == {"s.toml": "scene", "m.obj": "mesh", "a.npy": "npy", "other.npz": "npz", "notes.txt": "unknown",
                     "renamed.bin": SOLUTION, "solution.npz": SOLUTION, "fit.npz": FIT}
    assert require_format(renamed, (SOLUTION,)) == SOLUTION
    with pytest.raises(InputError, match="'.*fit.npz' is a fit.npz, not a solution.npz"):
        require_format(tmp_path / "fit.npz", (SOLUTION,), "solution")
    with pytest.raises(InputError, match="is not a fit.npz or a solution.npz: it is a scene file"):
        require_format(tmp_path / "s.toml", (FIT, SOLUTION))
    with pytest.raises(InputError, match="is a solution.npz, not a scene"):
        load_scene(solution)


# -- this sweep: malformed scenes and archives ----------------------------------------

MALFORMED_SCENES = {
    "binary garbage toml": ("scene.toml", bytes(range(256)) * 4, "cannot read|malformed"),
    "latin-1 toml": ("scene.toml", "name = 'caf\xe9'\n".encode("latin-1"), "cannot read"),
    "toml array of objects not tables": ("scene.toml", ("objects = [1, 2]\n" + GOOD_MATERIAL).encode(), "must be a table"),
    "toml name not a string": ("scene.toml", (GOOD_MATERIAL + CUBE.format(name="3")).encode(), "needs a 'name'"),
    "toml material not a table": ("scene.toml", b"materials = 3\n[[objects]]\nname='a'\nbuiltin='cube'\nmaterial='m'\n", "materials"),
    "toml huge exponent": ("scene.toml", b"[materials.m]\nspecular=0.5\nexponent=1e400\n" + CUBE.format(name="'a'").encode(), "finite|number"),
    "toml nul in material name": ("scene.toml", b'[materials."m\\u0000"]\ndiffuse=0.5\n' + CUBE.format(name="'a'").encode(), "unknown material 'm'"),
    "empty obj": ("a.obj", b"", "no triangle|cannot read"),
    "obj of garbage": ("a.obj", b"\x00\xff" * 500, "no triangle|cannot read"),
    "obj with only points": ("a.obj", b"v 0 0 0\nv 1 0 0\n", "no triangle|cannot read"),
    "obj face out of range": ("a.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", "no triangle|cannot read|index"),
    "glb of garbage": ("a.glb", b"glTF" + b"\xff" * 40, "cannot read|no triangle"),
    "gltf not json": ("a.gltf", b"{not json", "cannot read"),
    "gltf json list": ("a.gltf", b"[1, 2]", "cannot read|no triangle"),
    "ply truncated": ("a.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 1000\nproperty float x\nend_header\n\x00", "cannot read|no triangle"),
    "stl of garbage": ("a.stl", b"solid x\nfacet normal nan\n", "cannot read|no triangle"),
    "off header only": ("a.off", b"OFF\n3 1 0\n", "cannot read|no triangle"),
    "unknown suffix": ("a.xyz", b"1 2 3\n", "unknown scene format"),
    "a numpy array": ("a.npy", None, "unknown scene format"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED_SCENES))
@pytest.mark.parametrize("command", ["scene-info", "solve"])
def test_malformed_scenes_are_one_line(case, command, tmp_path, capsys):
    name, data, fragment = MALFORMED_SCENES[case]
    path = tmp_path / name
    if data is None:
        np.save(path, np.zeros(3))
    else:
        path.write_bytes(data)
    argv = [command, path] + (["-o", tmp_path / "s.npz"] if command == "solve" else [])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SceneWarning)
        err = refused(argv, capsys)
    assert __import__("re").search(fragment, err), err
    assert not (tmp_path / "s.npz").exists()


MALFORMED_ARCHIVES = {
    "empty": lambda p: p.write_bytes(b""),
    "text": lambda p: p.write_text("hello"),
    "truncated zip": lambda p: p.write_bytes(tiny_solution(p).read_bytes()[:200]),
    "zip of nothing": lambda p: __import__("zipfile").ZipFile(p, "w").close(),
    "npz without meta": lambda p: np.savez(p, x=np.zeros(3)),
    "meta a number": lambda p: replace_member(tiny_solution(p), "meta.npy", npy_bytes((), "<f8", b"\0" * 8)),
    "meta not json": lambda p: replace_member(tiny_solution(p), "meta.npy", _npy(np.array("{"))),
    "meta json list": lambda p: replace_member(tiny_solution(p), "meta.npy", _npy(np.array("[1]"))),
    "a fit, not a solution": lambda p: write_archive(p, {"format": FIT, "version": 1}, {}),
    "radiance object dtype": lambda p: replace_member(tiny_solution(p), "plate/radiance.npy", npy_bytes((9, 1, 3), "|O", b"")),
    "radiance header garbage": lambda p: replace_member(tiny_solution(p), "plate/radiance.npy", b"\x93NUMPY\x01\x00\xff\xff{garbage"),
    "npy version 9": lambda p: replace_member(tiny_solution(p), "plate/radiance.npy", b"\x93NUMPY\x09\x00" + b"\0" * 30),
    "negative shape": lambda p: replace_member(tiny_solution(p), "plate/radiance.npy", npy_bytes((9, 1, 3), "<f4")[:10]
                                               + b"{'descr': '<f4', 'fortran_order': False, 'shape': (-9, 1, 3), }".ljust(118) + b"\n"),
}


def _npy(array):
    buf = __import__("io").BytesIO()
    np.save(buf, array)
    return buf.getvalue()


@pytest.mark.parametrize("case", sorted(MALFORMED_ARCHIVES))
def test_malformed_solutions_are_one_line_for_fit(case, tmp_path, capsys):
    path = tmp_path / "solution.npz"
    MALFORMED_ARCHIVES[case](path)
    refused(["fit", path, "-o", tmp_path / "f.npz"], capsys)
    with pytest.raises(InputError):
        load_solution(path)
    assert not (tmp_path / "f.npz").exists()


# -- this sweep: output paths ---------------------------------------------------------

OUTPUT_HAZARDS = {
    "a directory": (lambda d: (d / "out.npz").mkdir() or d / "out.npz", "is a directory"),
    "a missing directory": (lambda d: d / "missing" / "out.npz", "does not exist"),
    "a dangling symlink into a missing directory": (
        lambda d: (d / "out.npz").symlink_to(d / "missing" / "x.npz") or d / "out.npz", "does not exist"),
    "a symlink to a directory": (lambda d: (d / "dir").mkdir() or (d / "out.npz").symlink_to(d / "dir") or d / "out.npz",
                                 "is a directory"),
    "a device": (lambda d: (d / "out.npz").symlink_to("/dev/null") or d / "out.npz", "not a regular file"),
    "a name too long": (lambda d: d / ("x" * 300 + ".npz"), "more than the 255"),
    "a NUL in the name": (lambda d: str(d / "a\0b.npz"), "NUL"),
    "the wrong suffix": (lambda d: d / "out.txt", "must end in .npz"),
    "a parent that is a file": (lambda d: (d / "f").write_text("x") and d / "f" / "out.npz", "is a file"),
}


@pytest.mark.parametrize("hazard", sorted(OUTPUT_HAZARDS))
@pytest.mark.parametrize("command", ["solve", "fit"])
def test_output_hazards_are_refused_before_any_work(hazard, command, solution, tmp_path, capsys):
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    make, fragment = OUTPUT_HAZARDS[hazard]
    out = make(out_dir)
    before = sorted(os.listdir(out_dir))
    source = "cornell" if command == "solve" else solution
    refused([command, source, "-o", out], capsys, fragment)
    assert sorted(os.listdir(out_dir)) == before


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only directories")
def test_a_read_only_directory_is_refused(solution, tmp_path, capsys):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(stat.S_IRUSR | stat.S_IXUSR)
    try:
        refused(["fit", solution, "-o", ro / "f.npz"], capsys, "cannot write into directory")
    finally:
        ro.chmod(stat.S_IRWXU)


def test_an_existing_output_is_kept_when_the_command_fails(solution, tmp_path, capsys):
    keep = tmp_path / "keep.npz"
    keep.write_bytes(b"precious")
    refused(["solve", "cornell", "-o", keep, "--photons", "0"], capsys, "--photons")
    refused(["fit", solution, "-o", keep, "--target", "nan"], capsys, "--target")
    broken = tmp_path / "broken.npz"
    broken.write_bytes(b"not a zip")
    refused(["fit", broken, "-o", keep], capsys, "not a solution.npz")
    assert keep.read_bytes() == b"precious"


def test_the_input_is_never_the_output(solution, tmp_path, capsys):
    link = tmp_path / "link.npz"
    link.symlink_to(solution)
    before = solution.read_bytes()
    refused(["fit", solution, "-o", link], capsys, "is the input file")
    scene = write(tmp_path / "scene.npz", "")  # a scene given its output's name
    refused(["solve", scene, "-o", scene], capsys, "is the input file")
    assert solution.read_bytes() == before


# -- this sweep: flag extremes --------------------------------------------------------

EXTREMES = ["0", "-1", "1e400", "100000000000000000000000", "nan", "inf", "-inf", "many"]
# values a flag accepts, with the reason: these run a full solve or fit and are not swept here
ACCEPTED = {
    ("--light-samples", "0"),  # no light samples: the gather alone
    ("--kernel-rings", "0"),  # a vertex's own hat function
    ("--extra-gather", "0"), ("--extra-gather", "100000000000000000000000"),  # at most: the tolerance stops it
    ("--gather-tolerance", "0"), ("--gather-tolerance", "100000000000000000000000"),
    ("--max-edge", "100000000000000000000000"),  # no refinement
    ("--vertex-budget", "100000000000000000000000"),  # a budget the refinement never reaches
    ("--seed", "0"),
    ("--threads", "100000000000000000000000"),  # one per core at most
}
SOLVE_FLAGS = ["--photons", "--gather-samples", "--light-samples", "--grid", "--max-edge", "--kernel-rings",
               "--extra-gather", "--gather-tolerance", "--visibility-samples", "--emitter-nodes", "--vertex-budget",
               "--seed", "--threads"]
FIT_ACCEPTED = {("--lights", "0"), ("--iterations", "0")}
FIT_FLAGS = ["--lights", "--target", "--model-target", "--max-lights", "--iterations", "--probe-size"]


@pytest.mark.parametrize("value", EXTREMES)
@pytest.mark.parametrize("flag", SOLVE_FLAGS)
def test_solve_flag_extremes_are_refused_in_one_line(flag, value, tmp_path, capsys):
    if (flag, value) in ACCEPTED:
        pytest.skip("a value the flag accepts")
    scene = write(tmp_path / "glossy.toml", GLOSSY)  # a glossy object: every knob matters
    refused(["solve", scene, "-o", tmp_path / "s.npz", flag, value], capsys, flag.lstrip("-").split("-")[0])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["glossy.toml"]


@pytest.mark.parametrize("value", EXTREMES)
@pytest.mark.parametrize("flag", FIT_FLAGS)
def test_fit_flag_extremes_are_refused_in_one_line(flag, value, solution, tmp_path, capsys):
    if (flag, value) in FIT_ACCEPTED:
        pytest.skip("a value the flag accepts")
    refused(["fit", solution, "-o", tmp_path / "f.npz", flag, value], capsys)
    assert not (tmp_path / "f.npz").exists()


@pytest.mark.parametrize("bounds", [("0", "0"), ("-1", "5"), ("nan", "5"), ("1", "inf"), ("1", "1e400"), ("5", "1")])
def test_fit_exponent_bounds_extremes_are_refused(bounds, solution, tmp_path, capsys):
    refused(["fit", solution, "-o", tmp_path / "f.npz", "--exponent-bounds", *bounds], capsys)


@pytest.mark.parametrize("value", ["-1", "1e400", "nan", "inf", "0"])
@pytest.mark.parametrize("flag", ["--max-edge", "--vertex-budget"])
def test_scene_info_flag_extremes_are_refused(flag, value, capsys):
    refused(["scene-info", "cornell", flag, value], capsys)


# -- in a child process: what only a real process shows --------------------------------


@pytest.mark.subprocess
def test_a_fifo_scene_does_not_block_the_command(tmp_path):
    fifo = tmp_path / "scene.toml"
    os.mkfifo(fifo)
    env = {**os.environ, "TMPDIR": str(tmp_path)}
    result = subprocess.run([sys.executable, "-m", "display", "scene-info", str(fifo)], capture_output=True,
                            text=True, timeout=120, env=env)
    assert result.returncode == 2 and "named pipe" in result.stderr and result.stderr.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.toml"]


@pytest.mark.subprocess
def test_a_nul_named_object_fails_before_the_solve_in_a_real_run(tmp_path):
    scene = write(tmp_path / "s.toml", GOOD_MATERIAL + CUBE.format(name='"a\\u0000b"'))
    result = subprocess.run([sys.executable, "-m", "display", "solve", str(scene), "-o", str(tmp_path / "s.npz")],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and "U+0000" in result.stderr and "Traceback" not in result.stderr
    assert not Path(tmp_path / "s.npz").exists()


FIT_FLAG_EXTREMES = [
    ["--search-samples", "0"], ["--search-samples", "-5"], ["--search-samples", str(2**41)], ["--search-samples", "1e3"],
    ["--block-samples", "0"], ["--block-samples", "x"], ["--model-target", "nan"], ["--model-target", "inf"],
    ["--model-target", "-1"], ["--probe-size", "0"], ["--probe-size", "129"], ["--probe-size", "auto2"],
    ["--lights", "-1"], ["--lights", "65"], ["--lights", "many"], ["--max-lights", "0"], ["--max-lights", "65"],
    ["--exponent-bounds", "0", "1"], ["--exponent-bounds", "2", "1"], ["--exponent-bounds", "nan", "1"],
    ["--exponent-bounds", "1", "inf"], ["--iterations", "-1"], ["--target", "0"], ["--target", "nan"],
    ["--workers", "0"], ["--workers", "-1"], ["--scheduler", "ftp://host:1"], ["--scheduler", "tcp://"],
    ["--model", "lights+probe"], ["--method", "fast"], ["--quality", "ultra"],
]


@pytest.mark.parametrize("flags", FIT_FLAG_EXTREMES, ids=" ".join)
def test_every_fit_flag_at_its_extremes_is_refused_in_one_line_and_writes_nothing(tmp_path, capsys, solution, flags):
    """The fit's flags at and past their limits (zero, negative, NaN, infinite, too large,
    not a number, an unknown word): one line, exit 2, no fit.npz and nothing else left."""
    out = tmp_path / "fit.npz"
    before = sorted(p.name for p in tmp_path.iterdir())
    refused(["fit", solution, "-o", out, *flags], capsys)
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == before
